"""Built-in example models with their published reference results.

Each builder returns an :class:`Example`: the system, the recommended simulation settings, the
ids of interesting items, and a ``check`` function that compares a result with the reference
(``../shared/reference`` R5: the IFToMM multibody benchmark problems).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from .rotation import rotation


@dataclass
class Example:
    """A ready-to-run model."""

    name: str
    description: str
    system: _core.System
    end_time: float
    step_size: float
    solver: _core.GeneralizedAlpha
    output_interval: float
    items: dict[str, Any] = field(default_factory=dict)
    reference: dict[str, Any] = field(default_factory=dict)
    check: Callable[[Any], dict[str, float]] | None = None


def pendulum() -> Example:
    """IFToMM A01: a 1 kg point mass on a massless 1 m link (a distance constraint), released at
    rest from x = +1 m, gravity 9.81 m/s^2 along -y. Exact positions at t = 0.5, 1, 5, 10 s."""
    system = _core.System(gravity=(0.0, -9.81, 0.0))
    mass = system.add_point_mass(1.0, position=(1.0, 0.0, 0.0), name="mass")
    pivot = system.add_marker(system.ground, name="pivot")
    bob = system.add_marker(mass, name="bob")
    link = system.add_distance_joint(pivot, bob, 1.0, name="link")
    sensor = system.add_sensor(bob, "position", name="bob position")
    reference = {
        0.5: (0.391048791551, -0.920369948785),
        1.0: (-0.986291751132, -0.165010853126),
        5.0: (0.942305435044, -0.334754338414),
        10.0: (0.275087462576, -0.961419205099),
    }

    def check(result: Any) -> dict[str, float]:
        errors = {}
        for t, (x, y) in reference.items():
            k = int(np.argmin(np.abs(result.time - t)))
            if abs(result.time[k] - t) < 1e-9:
                p = result.sensor(sensor)[k]
                errors[f"position error at t = {t:g} s"] = float(max(abs(p[0] - x), abs(p[1] - y)))
        return errors

    return Example(
        name="pendulum",
        description="IFToMM A01 simple pendulum (point mass on a distance constraint)",
        system=system,
        end_time=10.0,
        step_size=5e-5,
        solver=_core.GeneralizedAlpha(1.0),
        output_interval=0.01,
        items={"mass": mass, "link": link, "bob": sensor},
        reference=reference,
        check=check,
    )


def four_bar(n: int = 2) -> Example:
    """IFToMM A02 N-four-bar in 3D: 2N+1 uniform 1 kg, 1 m links, gravity 9.81 m/s^2 along -y.
    Cranks stand vertically on pivots at x = 0..N, couplers lie horizontally at y = 1; the top
    of the first crank, B0, starts at 1 m/s along +x. Cranks: revolute joints to the ground;
    couplers: revolute joint to crank k and an in-line joint (in-plane position only) to crank
    k+1, so that the spatial model has no redundant equations. The mechanism passes singular
    configurations (cranks horizontal) twice per turn. Exact B0 at t = 10 s for N = 2."""
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    system = _core.System(gravity=(0.0, -9.81, 0.0))
    # A slender rod along its local x axis (the axial moment is irrelevant for planar motion).
    inertia = (5e-5, 1.0 / 12.0, 1.0 / 12.0)
    up = rotation("z", np.pi / 2)  # crank frame: local x points up
    to_joint = rotation("z", -np.pi / 2)  # marker axes parallel to the global axes
    tops = []
    cranks = []
    pivots = []
    for k in range(n + 1):
        crank = system.add_rigid_body(
            1.0,
            inertia,
            position=(k, 0.5, 0.0),
            orientation=up,
            velocity=(0.5, 0.0, 0.0),
            angular_velocity=(0.0, 0.0, -1.0),
            name=f"crank {k}",
        )
        ground_marker = system.add_marker(system.ground, position=(k, 0.0, 0.0))
        bottom = system.add_marker(crank, position=(-0.5, 0.0, 0.0), orientation=to_joint)
        pivots.append(system.add_revolute_joint(ground_marker, bottom, name=f"pivot {k}"))
        tops.append(
            system.add_marker(crank, position=(0.5, 0.0, 0.0), orientation=to_joint, name=f"B{k}")
        )
        cranks.append(crank)
    couplers = []
    for k in range(n):
        coupler = system.add_rigid_body(
            1.0,
            inertia,
            position=(k + 0.5, 1.0, 0.0),
            velocity=(1.0, 0.0, 0.0),
            name=f"coupler {k}",
        )
        left = system.add_marker(coupler, position=(-0.5, 0.0, 0.0))
        right = system.add_marker(coupler, position=(0.5, 0.0, 0.0))
        system.add_revolute_joint(tops[k], left, name=f"coupler {k} left")
        system.add_inline_joint(tops[k + 1], right, name=f"coupler {k} right")
        couplers.append(coupler)
    b0_position = system.add_sensor(tops[0], "position", name="B0 position")
    b0_velocity = system.add_sensor(tops[0], "velocity", name="B0 velocity")
    reference = {
        "position": (0.3284581115, 0.9445185382),
        "velocity": (1.4230514702, -0.4948688455),
    }

    def check(result: Any) -> dict[str, float]:
        if n != 2 or abs(result.time[-1] - 10.0) > 1e-9:
            return {}
        p = result.sensor(b0_position)[-1]
        v = result.sensor(b0_velocity)[-1]
        return {
            "B0 position error at t = 10 s": float(np.max(np.abs(p[:2] - reference["position"]))),
            "B0 velocity error at t = 10 s": float(np.max(np.abs(v[:2] - reference["velocity"]))),
        }

    return Example(
        name="four-bar",
        description=f"IFToMM A02 N-four-bar, N = {n} ({2 * n + 1} rigid links, 3D)",
        system=system,
        end_time=10.0,
        step_size=2e-4,
        solver=_core.GeneralizedAlpha(0.9),
        output_interval=0.01,
        items={
            "cranks": cranks,
            "couplers": couplers,
            "pivots": pivots,
            "B0 position": b0_position,
            "B0 velocity": b0_velocity,
        },
        reference=reference if n == 2 else {},
        check=check,
    )


EXAMPLES: dict[str, Callable[[], Example]] = {"four-bar": four_bar, "pendulum": pendulum}
"""Builders of the built-in examples, by name."""
