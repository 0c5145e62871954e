"""A swinging arm for study tests: a rigid rod on a hinge under gravity, released horizontal.
``fail_at`` makes a callback force raise at that time (a deliberately failing case);
``die_at`` ends the worker process itself at that time (as the out-of-memory killer or a crash
in native code would), and ``die_building`` as the model is built."""

from __future__ import annotations

import os

import flexmbd as fm


def swinging_arm(
    length: float = 1.0,
    mass: float = 1.0,
    fail_at: float | None = None,
    die_at: float | None = None,
    die_building: bool = False,
):
    if die_building:
        os._exit(3)
    system = fm.System(gravity=(0.0, -9.81, 0.0))
    arm = system.add_rigid_body(
        mass,
        (1e-4, mass * length**2 / 12, mass * length**2 / 12),
        position=(length / 2, 0.0, 0.0),
        name="arm",
    )
    system.add_revolute_joint(
        system.add_marker(system.ground),
        system.add_marker(arm, position=(-length / 2, 0.0, 0.0)),
        name="hinge",
    )
    if fail_at is not None:

        def brake(t, q, qd):
            if t > fail_at:
                raise RuntimeError(f"deliberate failure at t = {t:.3f}")
            return [0.0] * len(q)

        system.add_callback_force([arm], brake, name="brake")
    if die_at is not None:

        def fatal(t, q, qd):
            if t > die_at:
                os._exit(3)
            return [0.0] * len(q)

        system.add_callback_force([arm], fatal, name="fatal")
    system.add_sensor(system.add_marker(arm, position=(length / 2, 0, 0)), "position", name="tip")
    return system
