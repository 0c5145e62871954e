"""Spin-up R3 under refinement (issue 30, item c): where the single-body FFRF beam converges,
and an independent geometrically exact model of the same beam.

    python benchmarks/spin_up_refinement.py            # about 80 s (80 elements: 50 s of it)
    python benchmarks/spin_up_refinement.py --quick    # without the 80-element runs

Prints min v_tip (m) of
1. the built-in example (one deformable body, nodal, geometric stiffness) at 10-80 elements,
   with the von Karman strain (`geometric_stiffness=True`) and with the co-rotational beam
   (`geometric_stiffness="corotational"`);
2. the same beam as 2, 4, 8 deformable bodies joined by fixed joints (40 elements in all;
   `flexmbd.examples.spin_up(bodies=...)`);
3. a chain of rigid links with rotational springs (a Hencky chain: EI/Le between links,
   2 EI/Le at the clamped root), exact kinematics, with Richardson extrapolation;
4. the quasi-static tip deflection at t = 6.75 s (elastic coordinates balancing the prescribed
   speed and acceleration) of the FFRF beam, of the linear theory (Hermite beam elements with
   the exact tension N(x) = rho A W^2 (L^2 - x^2)/2 and centrifugal softening) and of the exact
   elastica (a boundary-value problem, scipy's solve_bvp).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.integrate import solve_bvp

import flexmbd as fm

L, EI, RHO_A = 10.0, 1.4e4, 1.2
TS, WS = 15.0, 6.0
REFERENCE = -0.5737


def hub_angle(t: float) -> tuple[float, float, float]:
    c = TS / (2 * np.pi)
    if t <= TS:
        return (
            WS / TS * (t**2 / 2 + c**2 * (np.cos(t / c) - 1)),
            WS / TS * (t - c * np.sin(t / c)),
            WS / TS * (1 - np.cos(t / c)),
        )
    return WS * (t - TS / 2), WS, 0.0


def lag(result: fm.Result, tip: np.ndarray) -> tuple[float, float]:
    """min v_tip in the frame turning with the hub, and its time."""
    theta = np.array([hub_angle(t)[0] for t in result.time])
    v = -np.sin(theta) * tip[:, 0] + np.cos(theta) * tip[:, 1]
    k = int(np.argmin(v))
    return float(v[k]), float(result.time[k])


def run(system: fm.System, step: float = 5e-3) -> tuple[fm.Result, float]:
    start = time.perf_counter()
    result = fm.simulate(system, 8.0, step, solver=fm.GeneralizedAlpha(0.9), output_interval=0.01)
    return result, time.perf_counter() - start


def chain(links: int) -> tuple[fm.System, fm.BodyId, float]:
    le = L / links
    mass = RHO_A * le
    system = fm.System()
    hub = system.add_rigid_body(1.0, (1.0, 1.0, 1.0))
    ground, hub_marker = system.add_marker(system.ground), system.add_marker(hub)
    system.add_revolute_joint(ground, hub_marker)
    system.add_angle_driver(ground, hub_marker, fm.UserFunction(hub_angle, derivatives=True))
    previous, end = hub, (0.0, 0.0, 0.0)
    for k in range(links):
        inertia = (1e-9, mass * le**2 / 12, mass * le**2 / 12)
        link = system.add_rigid_body(mass, inertia, position=((k + 0.5) * le, 0, 0))
        a, b = (
            system.add_marker(previous, position=end),
            system.add_marker(link, position=(-le / 2, 0, 0)),
        )
        system.add_revolute_joint(a, b)
        system.add_rotational_spring_damper(a, b, stiffness=(2 if k == 0 else 1) * EI / le)
        previous, end = link, (le / 2, 0.0, 0.0)
    return system, previous, le


def quasi_static(t: float = 6.75) -> None:
    theta, speed, accel = hub_angle(t)

    def rhs(s, y):
        x, yy, th, fx, fy, m = y
        qx, qy = RHO_A * (speed**2 * x + accel * yy), RHO_A * (speed**2 * yy - accel * x)
        return np.vstack(
            [np.cos(th), np.sin(th), m / EI, -qx, -qy, np.sin(th) * fx - np.cos(th) * fy]
        )

    def bc(a, b):
        return np.array([a[0], a[1], a[2], b[3], b[4], b[5]])

    s = np.linspace(0, L, 200)
    guess = np.zeros((6, s.size))
    guess[0] = s
    exact = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=100000).y[1, -1]

    gauss, weights = np.polynomial.legendre.leggauss(6)
    gauss, weights = (gauss + 1) / 2, weights / 2
    n = 40
    le = L / n
    size = 2 * (n + 1)
    stiffness, mass, load = np.zeros((size, size)), np.zeros((size, size)), np.zeros(size)
    ke = (
        EI
        / le**3
        * np.array(
            [
                [12, 6 * le, -12, 6 * le],
                [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                [-12, -6 * le, 12, -6 * le],
                [6 * le, 2 * le**2, -6 * le, 4 * le**2],
            ]
        )
    )
    for e in range(n):
        block = slice(2 * e, 2 * e + 4)
        stiffness[block, block] += ke
        for xi, w in zip(gauss, weights, strict=True):
            x = (e + xi) * le
            shape = np.array(
                [
                    1 - 3 * xi**2 + 2 * xi**3,
                    le * (xi - 2 * xi**2 + xi**3),
                    3 * xi**2 - 2 * xi**3,
                    le * (xi**3 - xi**2),
                ]
            )
            slope = np.array(
                [
                    (-6 * xi + 6 * xi**2) / le,
                    1 - 4 * xi + 3 * xi**2,
                    (6 * xi - 6 * xi**2) / le,
                    3 * xi**2 - 2 * xi,
                ]
            )
            tension = RHO_A * speed**2 * (L**2 - x**2) / 2
            stiffness[block, block] += w * le * tension * np.outer(slope, slope)
            mass[block, block] += w * le * RHO_A * np.outer(shape, shape)
            load[block] += w * le * (-RHO_A * accel * x) * shape
    linear = np.linalg.solve((stiffness - speed**2 * mass)[2:, 2:], load[2:])[-2]

    ffrf = {}
    for kind in (True, "corotational"):
        example = fm.examples.spin_up(geometric_stiffness=kind, elements=40)
        model = example.system.compile()
        q = np.array(model.initial_coordinates)
        q[3:7] = [np.cos(theta / 2), 0, 0, np.sin(theta / 2)]  # the hub's angle at t
        state = fm.equilibrium(model, t, coordinates=q)
        ffrf[kind] = state.node_displacements(example.items["beam"])[-1, 1]
    print(
        f"quasi-static v_tip at t = {t} s: exact elastica {exact:.5f}, linear theory "
        f"{linear:.5f} ({linear / exact - 1:+.2%}), "
        f"FFRF beam (40 el.) von Karman {ffrf[True]:.5f} ({ffrf[True] / exact - 1:+.2%}), "
        f"co-rotational {ffrf['corotational']:.5f} ({ffrf['corotational'] / exact - 1:+.3%})"
    )


def main() -> None:
    quick = "--quick" in sys.argv
    print(f"R3 reference min v_tip = {REFERENCE} m at 6.75 s")
    for kind in (True, "corotational"):
        for n in (10, 20, 40) if quick else (10, 20, 40, 80):
            example = fm.examples.spin_up(geometric_stiffness=kind, elements=n)
            result, seconds = run(example.system)
            tip = result.node_positions(example.items["beam"], [n + 1])[:, 0, :]
            v, t = lag(result, tip)
            steps = result.statistics
            label = "von Karman" if kind is True else kind
            print(
                f"one body ({label}), {n:2d} elements: min v_tip {v:.5f} at {t:.2f} s "
                f"({v / REFERENCE - 1:+.3%}); "
                f"{seconds:.1f} s, {steps['steps']} steps, {steps['rejected_steps']} rejected"
            )
    for parts in (2, 4, 8):
        example = fm.examples.spin_up(elements=40, bodies=parts)
        result, seconds = run(example.system)
        error = example.check(result)["min v_tip error (m)"]
        print(
            f"{parts} bodies x {40 // parts:2d} elements: min v_tip error {error:.5f} m "
            f"({error / -REFERENCE:.2%} of R3); {seconds:.1f} s"
        )
    values = {}
    for links in (10, 20, 40):
        system, last, le = chain(links)
        result, seconds = run(system, 2e-3)
        tip = result.position(last) + result.orientation(last)[:, :, 0] * (le / 2)
        values[links], t = lag(result, tip)
        print(
            f"rigid-link chain, {links} links: min v_tip {values[links]:.5f} at {t:.2f} s; "
            f"{seconds:.1f} s"
        )
    for a, b in ((10, 20), (20, 40)):
        print(f"  Richardson (order 2) of {a} and {b} links: {(4 * values[b] - values[a]) / 3:.5f}")
    quasi_static()


if __name__ == "__main__":
    main()
