"""Dynamics of deformable bodies in flexmbd, side by side with Exudyn if it is installed:
steps per second, Newton iterations per step and the largest difference of the trajectories.

Models (`flexible_models.py`): the reduced flexible pendulum (Craig-Bampton, 16 modes), the
flexible slider-crank (reduced rod, 12 modes), and the unreduced pendulum bar with about 1k,
10k and 50k elastic coordinates. Both codes use the same finite-element matrices and modes and
implicit generalized-alpha (index 3, spectral radius 0.9) at the same fixed step.

    python benchmarks/flexible_dynamics.py pendulum          # flexmbd and Exudyn
    python benchmarks/flexible_dynamics.py slider-crank
    python benchmarks/flexible_dynamics.py nodal --size 10k
    python benchmarks/flexible_dynamics.py nodal --size 1k --no-exudyn

Timings are wall-clock times of the simulation call (model building excluded, initial
conditions included), best of `--repeat` runs, with numpy's BLAS on one thread. The reduced
models run the two codes in alternation, one run of each per round, and print the ratio of
each round besides that of the best runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import flexible_models as models  # noqa: E402
import numpy as np  # noqa: E402

import flexmbd as fm  # noqa: E402

#: Step size and end time of each model (two crank turns are 8377.6 steps: 8378, as Exudyn).
RUNS = {
    "pendulum": (1e-3, 1.0),
    "slider-crank": (1e-5, 8378 * 1e-5),
    "nodal": (1e-3, 0.05),
}


def build_pendulum(model: models.FlexibleModel) -> tuple[fm.System, dict]:
    """The hinged bar (pendulum or nodal): the frame on face x0, hinge about global z."""
    system = fm.System(gravity=models.GRAVITY)
    bar = system.add_flexible_body(model.body, name="bar")
    hinge = system.add_node_set_marker(bar, "x0")
    centroid = model.body.nodes[models.nodes_of(model, "x0")].mean(axis=0)
    pivot = system.add_marker(system.ground, position=centroid)
    system.add_revolute_joint(pivot, hinge, name="hinge")
    return system, {"body": bar, "tip face": "x1"}


def build_slider_crank(model: models.FlexibleModel) -> tuple[fm.System, dict]:
    """The slider-crank with the reduced rod."""
    crank_length, omega = models.CRANK, models.OMEGA
    system = fm.System()
    crank = system.add_rigid_body(
        0.1,
        (1e-6, 0.1 * crank_length**2 / 12, 0.1 * crank_length**2 / 12),
        center_of_mass=(crank_length / 2, 0, 0),
        angular_velocity=(0, 0, omega),
        name="crank",
    )
    # The rod's end-face centroids lie 3 mm off its frame's x axis (the mesh spans y, z = 0 ..
    # 0.006): its frame starts so that the x0 centroid is at the crank tip, with the velocity
    # of that point of the rigid mechanism at crank angle 0 (rod turning about the slider end).
    centroid = model.body.nodes[models.nodes_of(model, "x0")].mean(axis=0)
    w_rod = np.array([0.0, 0.0, -omega * crank_length / models.ROD])
    tip_velocity = np.array([0.0, omega * crank_length, 0.0])
    rod = system.add_flexible_body(
        model.body,
        position=np.array([crank_length, 0.0, 0.0]) - centroid,
        velocity=tip_velocity + np.cross(w_rod, -centroid),
        angular_velocity=w_rod,
        name="rod",
    )
    slider = system.add_point_mass(
        model.body.invariants.mass / 2, position=(crank_length + models.ROD, 0, 0), name="slider"
    )
    pivot, root = system.add_marker(system.ground), system.add_marker(crank)
    system.add_revolute_joint(pivot, root, name="bearing")
    system.add_angle_driver(pivot, root, fm.Polynomial([0.0, omega]), name="drive")
    system.add_revolute_joint(
        system.add_marker(crank, position=(crank_length, 0, 0)),
        system.add_node_set_marker(rod, "x0"),
        name="crank pin",
    )
    system.add_spherical_joint(
        system.add_node_set_marker(rod, "x1"), system.add_marker(slider), name="wrist pin"
    )
    along_x = fm.rotation("y", np.pi / 2)
    system.add_inline_joint(
        system.add_marker(system.ground, orientation=along_x),
        system.add_marker(slider),
        name="guide",
    )
    return system, {"body": rod, "tip face": "x1", "slider": slider}


def face_centroid(result: fm.Result, body, model: models.FlexibleModel, face: str) -> np.ndarray:
    """Trajectory of the centroid of a face of the deformed body (n, 3)."""
    ids = model.body.node_ids[models.nodes_of(model, face)]
    return result.node_positions(body, ids).mean(axis=1)


def run_flexmbd(name: str, size: str, repeat: int, solver: fm.GeneralizedAlpha) -> dict:
    model = {
        "pendulum": models.pendulum,
        "slider-crank": models.slider_crank_rod,
        "nodal": lambda: models.nodal(size),
    }[name]()
    build = build_slider_crank if name == "slider-crank" else build_pendulum
    step, end = RUNS[name]
    interval = 1e-4 if name == "slider-crank" else 0.01
    best = None
    for _ in range(repeat):
        system, items = build(model)
        compiled = system.compile()
        start = time.perf_counter()
        result = fm.simulate(compiled, end, step, output_interval=interval, solver=solver)
        wall = time.perf_counter() - start
        if best is None or wall < best[0]:
            best = (wall, result, items)
    wall, result, items = best
    stats = result.statistics
    return {
        "code": "flexmbd",
        "model": name,
        "size": size,
        "elastic_coordinates": model.body.elastic_coordinate_count,
        "steps": int(stats["steps"]),
        "wall": wall,
        "steps_per_second": stats["steps"] / wall,
        "newton_per_step": stats["newton_iterations"] / stats["steps"],
        "factorizations": int(stats["factorizations"]),
        "time": result.time,
        "tip": face_centroid(result, items["body"], model, items["tip face"]),
    }


def solve_timer(size: str, spectral_radius: float = 0.9, count: int = 50) -> Callable[[], float]:
    """A timer of one solve with the factorized constant elastic iteration matrix
    beta' M_ff + K_ff of the nodal body (what each Newton iteration of the condensed solver
    needs), factorized on one thread as the simulator's is: each call returns the mean of
    `count` consecutive solves (as the steps are timed: a best single solve is luckier than the
    mean of the solves inside a run)."""
    import scipy.sparse as sp

    from flexmbd.fe.modal import factorize

    body = models.nodal(size).body
    ga = fm.GeneralizedAlpha(spectral_radius)
    rho = ga.spectral_radius
    alpha_m, alpha_f = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
    beta = 0.25 * (0.5 + alpha_f - alpha_m + 0.5) ** 2
    step = RUNS["nodal"][0]
    matrix = sp.csc_matrix(body.invariants.k_ff) + sp.csc_matrix(body.invariants.m_ff) * (
        (1 - alpha_m) / ((1 - alpha_f) * beta * step**2)
    )
    free = body.reference.free_dofs
    factor = factorize(matrix, dofs=free, nodes=body.nodes, dofs_per_node=3, threads=1)
    rhs = np.random.default_rng(1).standard_normal(matrix.shape[0])
    factor.solve(rhs)

    def timer() -> float:
        start = time.perf_counter()
        for _ in range(count):
            factor.solve(rhs)
        return (time.perf_counter() - start) / count

    return timer


#: Steps of the longer run of `step_timer` per nodal size.
MARGINAL_STEPS = {"1k": 300, "10k": 100, "50k": 40}


def step_timer(size: str, solver: fm.GeneralizedAlpha) -> Callable[[], dict]:
    """A timer of the nodal pendulum's steps without its set-up (factorizations, initial
    conditions): each call runs 2 steps and `MARGINAL_STEPS[size]` + 2 steps and returns both
    wall times (their difference over the extra steps is the time per step)."""
    compiled = build_pendulum(models.nodal(size))[0].compile()
    step, steps = RUNS["nodal"][0], MARGINAL_STEPS[size]

    def timer() -> dict:
        walls = []
        for count in (2, steps + 2):
            start = time.perf_counter()
            result = fm.simulate(
                compiled, count * step, step, output_interval=count * step, solver=solver
            )
            walls.append(time.perf_counter() - start)
        stats = result.statistics
        return {
            "short": walls[0],
            "long": walls[1],
            "steps": steps,
            "newton_per_step": stats["newton_iterations"] / stats["steps"],
            "factorizations": int(stats["factorizations"]),
        }

    return timer


def nodal_timings(
    size: str,
    solver: fm.GeneralizedAlpha,
    repeat: int,
    each_round: Callable[[], None] | None = None,
) -> dict:
    """Time per step and of one solve, measured in alternation (`repeat` rounds, so that both
    see the same state of the machine; `each_round` runs first in every round, e.g. the other
    code): the step from the best short and long runs, the solve the best mean; also the time
    per step and the ratio to the solve of each round."""
    time_solve = solve_timer(size, solver.spectral_radius)
    time_steps = step_timer(size, solver)
    solves, runs = [], []
    for _ in range(repeat):
        if each_round is not None:
            each_round()
        solves.append(time_solve())
        runs.append(time_steps())
    steps = runs[0]["steps"]
    per_step = (min(r["long"] for r in runs) - min(r["short"] for r in runs)) / steps
    round_steps = [(r["long"] - r["short"]) / steps for r in runs]
    return {
        "per_step": per_step,
        "solve": min(solves),
        "round_steps": round_steps,
        "round_ratios": [t / s for t, s in zip(round_steps, solves, strict=True)],
        "newton_per_step": runs[0]["newton_per_step"],
        "factorizations": runs[0]["factorizations"],
    }


def run_exudyn(name: str, size: str, repeat: int) -> dict | None:
    """Exudyn's fastest configuration of the model (`exudyn_flexible.py`), or None if
    Exudyn is not installed."""
    try:
        import exudyn  # noqa: F401
    except ImportError:
        return None
    import exudyn_flexible

    config = exudyn_flexible.FASTEST_CONFIGS[name]
    return exudyn_flexible.run_best_of(name, size if name == "nodal" else None, config, repeat)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", choices=sorted(RUNS))
    parser.add_argument("--size", default="1k", choices=sorted(models.NODAL_SIZES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-exudyn", action="store_true")
    parser.add_argument("--spectral-radius", type=float, default=0.9)
    args = parser.parse_args(argv)
    solver = fm.GeneralizedAlpha(args.spectral_radius)
    if args.model == "nodal":
        # Exudyn's run and flexmbd's timings in alternation, one of each per round.
        exudyn_runs: list[dict] = []
        failure: list[dict | None] = []

        def exudyn_round() -> None:
            if failure:
                return
            other = run_exudyn(args.model, args.size, 1)
            if other is None or "error" in other:
                failure.append(other)
            else:
                exudyn_runs.append(other)

        each_round = None if args.no_exudyn else exudyn_round
        marginal = nodal_timings(args.size, solver, args.repeat, each_round)
        theirs = failure[0] if failure else None
        if exudyn_runs:
            theirs = min(exudyn_runs, key=lambda r: r["later_step_time_median"])
        solve = marginal["solve"]
        n_f = models.nodal(args.size).body.elastic_coordinate_count
        rounds = ", ".join(f"{r:.2f}" for r in marginal["round_ratios"])
        print(
            f"flexmbd  nodal {args.size} ({n_f} elastic coordinates): "
            f"{1e3 * marginal['per_step']:.2f} ms per step after the set-up "
            f"({marginal['newton_per_step']:.2f} Newton its/step, "
            f"{marginal['factorizations']} factorizations), one solve with the factorized "
            f"constant elastic matrix {1e3 * solve:.3f} ms: ratio "
            f"{marginal['per_step'] / solve:.2f} (each round: {rounds})"
        )
        if theirs is not None:
            if "error" in theirs:
                print(f"Exudyn   nodal {args.size}: {theirs['error']}")
            else:
                later = theirs["later_step_time_median"]
                each = ", ".join(
                    f"{r['later_step_time_median'] / t:.0f}"
                    for r, t in zip(exudyn_runs, marginal["round_steps"], strict=False)
                )
                print(
                    f"Exudyn   nodal {args.size} ({theirs['config']}): "
                    f"{1e3 * later:.1f} ms per step after the first "
                    f"(first {theirs['first_step_time']:.2f} s, "
                    f"{theirs['newton_iterations_per_step']:.2f} Newton its/step): "
                    f"flexmbd {later / marginal['per_step']:.0f}x faster per step "
                    f"(best of each; each round: {each})"
                )
        return 0
    # The two codes in alternation, `repeat` rounds of one run each (the VM's speed drifts over
    # seconds to minutes, so that runs of one code all taken before the other's compared two
    # speeds of the machine): the best run of each, and the ratio of each round.
    ours, theirs, rounds = None, None, []
    for _ in range(max(1, args.repeat)):
        mine = run_flexmbd(args.model, args.size, 1, solver)
        if ours is None or mine["wall"] < ours["wall"]:
            ours = mine
        if args.no_exudyn or (theirs is not None and "error" in theirs):
            continue
        other = run_exudyn(args.model, args.size, 1)
        if other is None or "error" in other:
            theirs = other
            continue
        rounds.append(mine["steps_per_second"] / other["steps_per_second"])
        if theirs is None or other["wall_time"] < theirs["wall_time"]:
            theirs = other
    print(
        f"flexmbd  {args.model} ({ours['elastic_coordinates']} elastic coordinates): "
        f"{ours['steps']} steps in {ours['wall']:.3f} s = {ours['steps_per_second']:.0f} steps/s "
        f"({1e3 * ours['wall'] / ours['steps']:.3f} ms/step), "
        f"{ours['newton_per_step']:.2f} Newton its/step, {ours['factorizations']} factorizations"
    )
    if theirs is not None:
        if "error" in theirs:
            print(f"Exudyn   {args.model}: {theirs['error']}")
            return 0
        print(
            f"Exudyn   {args.model} ({theirs['config']}, {theirs['exudyn_version']}): "
            f"{theirs['steps']} steps in {theirs['wall_time']:.3f} s = "
            f"{theirs['steps_per_second']:.0f} steps/s, "
            f"{theirs['newton_iterations_per_step']:.2f} Newton its/step"
        )
        times = np.asarray(theirs["outputs"]["times"])
        tip = np.asarray(theirs["outputs"]["x1_centroid"])
        ours_tip = np.array([np.interp(times, ours["time"], ours["tip"][:, k]) for k in range(3)]).T
        difference = float(np.max(np.abs(ours_tip - tip)))
        ratio = ours["steps_per_second"] / theirs["steps_per_second"]
        each = ", ".join(f"{r:.2f}" for r in rounds)
        print(
            f"ratio of steps per second: {ratio:.2f} (best runs; each round: {each}); "
            f"largest difference of the x1-face centroid trajectory: {difference:.2e} m"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
