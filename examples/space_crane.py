"""The space crane of the seed's Figure 2: inverse dynamics of a deformable mechanism.

Two 15 m aluminium booms (4 clamped modes each) on a turret carry a 2,000 kg payload in orbit
(no gravity); the turret, shoulder and elbow angles follow quintic rest-to-rest steps over T
and then hold. `fm.inverse_dynamics` gives the joint torques that produce this motion with
the booms' elastic deformation; they are compared with the torques of rigid booms, and the
payload's tracking error and residual vibration are measured for T = 30 s and 15 s. The run
checks itself: the torques' work equals the change of kinetic plus strain energy, replaying
the torques on the free crane reproduces the joint angles, and booms without modes need the
torques of rigid bodies of the same mass distribution.

    python examples/space_crane.py [--plot FILE.png]   (default: examples/space_crane.png)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import flexmbd as fm


def study(duration: float, **options) -> fm.InverseDynamics:
    crane = fm.examples.space_crane(duration=duration, **options)
    return fm.inverse_dynamics(crane.system, crane.end_time, crane.step_size)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--plot", default=str(Path(__file__).with_suffix(".png")))
    args = parser.parse_args()
    checks = {}
    runs = {}
    for duration in (30.0, 15.0):
        flexible, rigid = study(duration), study(duration, rigid=True)
        runs[duration] = (flexible, rigid)
        moving = flexible.time <= duration
        gap = np.linalg.norm(
            flexible.result.sensor("payload position") - rigid.result.sensor("payload position"),
            axis=1,
        )
        print(f"T = {duration:.0f} s:")
        for name in flexible.efforts:
            peak_f = np.abs(flexible.efforts[name]).max()
            peak_r = np.abs(rigid.efforts[name]).max()
            print(f"  {name:15s} peak torque: flexible booms {peak_f:9.1f} N m, rigid booms "
                  f"{peak_r:9.1f} N m")  # fmt: skip
        print(f"  payload off the rigid crane's path: up to {1e3 * gap[moving].max():.1f} mm "
              f"during the move, {1e3 * gap[~moving].max():.1f} mm after it (residual "
              "vibration)")  # fmt: skip
    flexible, rigid = runs[30.0]
    energy = flexible.result.total_energy - flexible.result.total_energy[0]
    checks["work - energy change, relative"] = (
        np.abs(flexible.work() - energy).max() / np.abs(energy).max()
    )
    replayed = flexible.replay()
    angles = flexible.joint_coordinates(replayed)
    checks["replayed joint angles, largest error (rad)"] = max(
        np.abs(angles[name] - flexible.prescribed(name, replayed.time)).max() for name in angles
    )
    no_modes = study(30.0, mode_count=0)
    checks["booms without modes vs rigid bodies, torques relative"] = max(
        np.abs(no_modes.efforts[n] - rigid.efforts[n]).max() / np.abs(rigid.efforts[n]).max()
        for n in rigid.efforts
    )
    limits = {
        "work - energy change, relative": 1e-6,
        "replayed joint angles, largest error (rad)": 1e-6,
        "booms without modes vs rigid bodies, torques relative": 1e-9,
    }
    for name, value in checks.items():
        print(f"{name}: {value:.2e} (limit {limits[name]:.0e})")
        assert value < limits[name], name
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
        for axis, name in zip(axes.flat, flexible.efforts, strict=False):
            for duration, style in ((30.0, "-"), (15.0, ":")):
                flex, rig = runs[duration]
                axis.plot(flex.time, flex.efforts[name] / 1e3, "C0" + style,
                          label=f"flexible booms, T = {duration:.0f} s")  # fmt: skip
                axis.plot(rig.time, rig.efforts[name] / 1e3, "C1" + style,
                          label=f"rigid booms, T = {duration:.0f} s")  # fmt: skip
            axis.set_title(f"{name.removesuffix(' drive')} torque")
            axis.set_ylabel("torque (kN m)")
            axis.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=8)
        axis = axes[1, 1]
        for duration, style in ((30.0, "-"), (15.0, ":")):
            flex, rig = runs[duration]
            gap = flex.result.sensor("payload position") - rig.result.sensor("payload position")
            axis.plot(flex.time, 1e3 * np.linalg.norm(gap, axis=1), "C2" + style,
                      label=f"T = {duration:.0f} s")  # fmt: skip
        axis.set_title("payload off the rigid crane's path")
        axis.set_ylabel("distance (mm)")
        axis.legend(fontsize=8)
        axis.grid(alpha=0.3)
        for axis in axes[1]:
            axis.set_xlabel("time (s)")
        figure.suptitle("Space crane: joint torques with flexible and rigid booms")
        figure.tight_layout()
        figure.savefig(args.plot, dpi=110)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
