"""Rigid slider-crank driven at constant speed: inverse dynamics.

A crank (0.15 m) turns at a prescribed 20 rad/s; a connecting rod (0.30 m) drives a slider on a
prismatic joint. The angle driver's multiplier is the driving torque. Without gravity and
friction the driving power must equal the rate of change of kinetic energy:
tau * omega = dT/dt, which this example checks, and it prints the largest joint forces.
"""

import numpy as np

import flexmbd as fm

R, L, OMEGA = 0.15, 0.30, 20.0


def build() -> tuple[fm.System, dict]:
    system = fm.System()
    crank = system.add_rigid_body(
        0.4, (1e-5, 0.4 * R**2 / 12, 0.4 * R**2 / 12), position=(R / 2, 0, 0)
    )
    rod = system.add_rigid_body(
        0.8, (1e-5, 0.8 * L**2 / 12, 0.8 * L**2 / 12), position=(R + L / 2, 0, 0)
    )
    slider = system.add_rigid_body(0.5, (1e-3, 1e-3, 1e-3), position=(R + L, 0, 0))
    pivot = system.add_marker(system.ground)
    crank_root = system.add_marker(crank, position=(-R / 2, 0, 0))
    system.add_revolute_joint(pivot, crank_root, name="main bearing")
    drive = system.add_angle_driver(pivot, crank_root, fm.Polynomial([0.0, OMEGA]), name="drive")
    crank_pin = system.add_revolute_joint(
        system.add_marker(crank, position=(R / 2, 0, 0)),
        system.add_marker(rod, position=(-L / 2, 0, 0)),
        name="crank pin",
    )
    # The slider moves along global x: its prismatic joint axis (marker z) points along x.
    along_x = fm.rotation("y", np.pi / 2)
    guide = system.add_prismatic_joint(
        system.add_marker(system.ground, orientation=along_x),
        system.add_marker(slider, orientation=along_x),
        name="guide",
    )
    # Closing the planar loop in 3D needs only the in-plane position of the wrist pin.
    wrist = system.add_inline_joint(
        system.add_marker(slider), system.add_marker(rod, position=(L / 2, 0, 0)), name="wrist pin"
    )
    return system, {"drive": drive, "crank pin": crank_pin, "guide": guide, "wrist": wrist}


def main() -> int:
    system, joints = build()
    result = fm.simulate(system, 2 * np.pi / OMEGA, 1e-4, output_interval=1e-3)
    torque = result.reaction_torque(joints["drive"])[:, 2]
    power = torque * OMEGA
    dkinetic = np.gradient(result.kinetic_energy, result.time)
    inner = slice(20, -2)  # after the start-up layer of the multipliers; one-sided gradient
    mismatch = np.max(np.abs(power[inner] - dkinetic[inner])) / np.max(np.abs(power[inner]))
    print(f"driving torque: {torque[inner].min():.3f} .. {torque[inner].max():.3f} N m")
    for name in ("crank pin", "guide", "wrist"):
        force = np.linalg.norm(result.reaction_force(joints[name]), axis=1)
        print(f"largest force in {name}: {force[inner].max():.2f} N")
    print(f"power balance tau w = dT/dt: largest relative mismatch {mismatch:.1e}")
    return int(mismatch > 1e-3)


if __name__ == "__main__":
    raise SystemExit(main())
