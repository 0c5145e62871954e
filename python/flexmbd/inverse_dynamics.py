"""Inverse dynamics of deformable mechanisms (seed section 3, control): the motion of the
joints is prescribed by drivers (profiles such as :class:`flexmbd.Step`), and the joint
efforts that produce it, with the elastic deformation of the bodies, are the drivers'
multipliers. :func:`inverse_dynamics` runs the driven mechanism and returns the efforts as
time series; :meth:`InverseDynamics.replay` applies them to the free mechanism (the drivers
replaced by the efforts, :meth:`System.with_drivers_as_efforts`), which must move as
prescribed: the check that the efforts are the ones that produce the motion."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _boundary
from .errors import InvalidModelError, InvalidParameterError, UnknownItemError
from .result import Result
from .simulation import simulate
from .system import System

#: The driver calls of a System and the reaction component that is their effort.
_DRIVERS = {"add_angle_driver": ("torque", "N m"), "add_translation_driver": ("force", "N")}


@dataclass(frozen=True)
class InverseDynamics:
    """The efforts of an inverse-dynamics run.

    Attributes:
        system: the driven system.
        result: its run (a record at every step).
        efforts: driver name -> effort at each record: the torque (N m) of an angle driver
            about its first marker's z axis, the force (N) of a translation driver along it,
            acting on the second marker's body (the driver's multiplier with the opposite
            sign: the generalized force conjugate to the joint coordinate, also where the
            markers sit on deformable bodies).
        units: driver name -> "N m" or "N".
        settings: the run's settings (end time, step size, solver), for the replay.
    """

    system: System
    result: Result
    efforts: dict[str, NDArray[np.float64]]
    units: dict[str, str]
    settings: dict[str, Any] = field(repr=False)

    @property
    def time(self) -> NDArray[np.float64]:
        """The record times (s)."""
        return self.result.time

    def rates(self, name: str) -> NDArray[np.float64]:
        """The prescribed rate f'(t) of driver `name` at the records (rad/s or m/s)."""
        function = self.system.driver_function(name)
        return np.array([_derivatives(function, t)[1] for t in self.time])

    def work(self, name: str | None = None) -> NDArray[np.float64]:
        """The work done by the effort of driver `name` (all drivers: None) from the start,
        at each record (J): the trapezoidal sum of effort times prescribed rate."""
        names = list(self.efforts) if name is None else [name]
        total = np.zeros(len(self.time))
        for each in names:
            if each not in self.efforts:  # (a bare KeyError)
                raise UnknownItemError(
                    f"no driver named {each!r} (drivers: {', '.join(map(repr, self.efforts))})",
                    item=str(each),
                )
            power = self.efforts[each] * self.rates(each)
            steps = 0.5 * (power[1:] + power[:-1]) * np.diff(self.time)
            total[1:] += np.cumsum(steps)
        return total

    def effort_functions(self) -> dict[str, Any]:
        """Each effort as a time function: the cubic spline through its records."""
        return {name: _boundary.Spline(self.time, effort) for name, effort in self.efforts.items()}

    def replay_system(self) -> System:
        """The free mechanism: the system with its drivers replaced by their efforts, and
        position and orientation sensors on the markers of each driven joint (``NAME
        marker 1 position``, ...) from which :meth:`joint_coordinates` measures its motion."""
        system = self.system.with_drivers_as_efforts(self.effort_functions())
        for name, markers in self._driver_markers().items():
            for k, marker in enumerate(markers, start=1):
                for quantity in ("position", "orientation"):
                    system.add_sensor(marker, quantity, name=f"{name} marker {k} {quantity}")
        return system

    def replay(self, **changes: Any) -> Result:
        """Runs the free mechanism under the efforts with the settings of the inverse run
        (`changes` replace some), from the same start: the inverse run's first state (with
        the velocities its drivers prescribed there) unless `initial_state` is given."""
        settings = {**self.settings, **changes}
        if settings.get("initial_state") is None:
            # (the replay started from the model's velocities: a driver moving at the start
            # lost its speed, and the arm of theta = 2 t ended at -0.15 rad for 1.0)
            settings["initial_state"] = self.result.state(0)
        return simulate(self.replay_system(), **settings)

    def joint_coordinates(self, replayed: Result) -> dict[str, NDArray[np.float64]]:
        """The coordinate of each driven joint in a replay (:meth:`replay`): the angle of
        marker 2's x axis from marker 1's about marker 1's z axis (continued over turns),
        or the slide of marker 2 along it, at each record; the inverse run prescribed
        ``driver_function(name)``."""
        out = {}
        for name in self.efforts:
            first = replayed.sensor(f"{name} marker 1 orientation").reshape(-1, 3, 3)
            second = replayed.sensor(f"{name} marker 2 orientation").reshape(-1, 3, 3)
            if self.units[name] == "N m":
                sine = np.einsum("ni,ni->n", first[:, :, 1], second[:, :, 0])
                cosine = np.einsum("ni,ni->n", first[:, :, 0], second[:, :, 0])
                out[name] = np.unwrap(np.arctan2(sine, cosine))
            else:
                offset = replayed.sensor(f"{name} marker 2 position") - replayed.sensor(
                    f"{name} marker 1 position"
                )
                out[name] = np.einsum("ni,ni->n", first[:, :, 2], offset)
        return out

    def prescribed(self, name: str, time: NDArray[np.float64]) -> NDArray[np.float64]:
        """The coordinate driver `name` prescribes at `time`."""
        function = self.system.driver_function(name)
        return np.array([_derivatives(function, t)[0] for t in time])

    def _driver_markers(self) -> dict[str, tuple[Any, Any]]:
        markers = {}
        for method, args, kwargs in self.system.building_calls:
            if method in _DRIVERS and kwargs.get("name") in self.efforts:
                pair = args[:2] if len(args) >= 2 else (kwargs["marker1"], kwargs["marker2"])
                markers[kwargs["name"]] = tuple(pair)
        return markers


def _derivatives(function: Any, t: float) -> tuple[float, float, float]:
    if isinstance(function, int | float):
        return (float(function), 0.0, 0.0)
    if hasattr(function, "derivatives") and callable(function.derivatives):
        return tuple(function.derivatives(t))
    h = 1e-6 * (1.0 + abs(t))
    return (function(t), (function(t + h) - function(t - h)) / (2 * h), 0.0)


def _recording_steps(solver: Any, step_size: float) -> Any:
    """`solver` with its steps at most `step_size` where it chooses them itself (dopri5,
    tr-bdf2, generalized-alpha's error control) and no largest step is given: with every
    joint driven its error control sees no error, and the steps grew fivefold each (a
    cycloidal lift of 1 s recorded at 7 times; its replay 0.07 m off)."""
    explicit = isinstance(solver, _boundary.ExplicitSolver)
    adaptive = (explicit and solver.method in ("dopri5", "tr-bdf2")) or (
        isinstance(solver, _boundary.GeneralizedAlpha) and solver.step_control == "error"
    )
    if not adaptive or solver.max_step_size is not None:
        return solver
    _, options = solver.__getnewargs_ex__()  # (the solver's settings, as keywords)
    return type(solver)(**{**options, "max_step_size": step_size})


def inverse_dynamics(
    system: System,
    end_time: float,
    step_size: float,
    *,
    drivers: list[str] | str | None = None,
    solver: Any = None,
    **settings: Any,
) -> InverseDynamics:
    """Runs `system`, whose joints' motion its drivers prescribe, and returns the efforts of
    `drivers` (names, or one name; default: every named angle and translation driver) at
    every step.

    The default solver is generalized-alpha with spectral radius 1 (no numerical damping),
    fixed steps (the replay meets the same step grid) and the velocities projected at every
    step (no start-up layer in the multipliers). `settings` go to
    :func:`flexmbd.simulate` (``start_time``, ``initial_state``, ...); records are taken at
    every step. An adaptive solver (dopri5, tr-bdf2, generalized-alpha's error control) takes
    steps of at most `step_size` unless given its own ``max_step_size``: with every joint
    driven its error control would let them grow without bound. Raises
    `InvalidParameterError` for an unknown driver name and `InvalidModelError` for a system
    without named drivers."""
    if not isinstance(system, System):
        raise InvalidParameterError(
            f"inverse_dynamics takes a flexmbd.System (its drivers are replaced for the replay), "
            f"got {type(system).__name__}",
            item="system",
        )
    named = {
        kwargs.get("name"): method
        for method, _, kwargs in system.building_calls
        if method in _DRIVERS and kwargs.get("name") is not None
    }
    if not named:
        raise InvalidModelError(
            "the system has no named angle or translation drivers: name the drivers whose "
            "efforts you want",
            item="drivers",
        )
    # (one name as a string was taken letter by letter: "no driver named 'm'")
    chosen = (
        list(named) if drivers is None else [drivers] if isinstance(drivers, str) else list(drivers)
    )
    for name in chosen:
        if name not in named:
            raise InvalidParameterError(
                f"no driver named {name!r}; drivers: {sorted(named)}", item=name
            )
    if "output_interval" in settings:
        raise InvalidParameterError(
            "an inverse-dynamics run records every step (its efforts are replayed on the same "
            "steps): give no output_interval",
            item="output_interval",
        )
    if solver is None:
        # No numerical damping (the work of the efforts balances the energy), and the
        # velocities projected at every step, which removes the start-up layer of the
        # multipliers: efforts accurate from the first step.
        solver = _boundary.GeneralizedAlpha(1.0, step_control="fixed", velocity_projection="always")
    else:
        solver = _recording_steps(solver, step_size)
    run = {"end_time": end_time, "step_size": step_size, "solver": solver, **settings}
    # The driven system with orientation sensors on the angle drivers' markers.
    driven = copy.copy(system)
    sensed = {}
    for method, args, kwargs in system.building_calls:
        if method == "add_angle_driver" and kwargs.get("name") in chosen:
            pair = args[:2] if len(args) >= 2 else (kwargs["marker1"], kwargs["marker2"])
            sensed[kwargs["name"]] = [
                driven.add_sensor(marker, "orientation", name=f"{kwargs['name']} marker {k}")
                for k, marker in enumerate(pair, start=1)
            ]
    result = simulate(driven, **run)
    efforts, units = {}, {}
    for name in chosen:
        multiplier = np.array(result.joint_multipliers(name)[:, 0])
        if name in sensed:
            # The angle driver's equation (y_i . x_j) cos f - (x_i . x_j) sin f = 0 is
            # rho sin(theta - f) with rho = |(y_i . x_j, x_i . x_j)|: its force on the
            # coordinates is -lambda rho dtheta/dq (rho = 1 for orthonormal marker axes; the
            # axes of markers on deformable bodies' nodes turn with the linearized elastic
            # rotation, and rho differs from 1 by its square).
            first, second = (result.sensor(s).reshape(-1, 3, 3) for s in sensed[name])
            sine = np.einsum("ni,ni->n", first[:, :, 1], second[:, :, 0])
            cosine = np.einsum("ni,ni->n", first[:, :, 0], second[:, :, 0])
            multiplier = multiplier * np.hypot(sine, cosine)
        # A translation driver's equation is x - f = 0: its force is -lambda dx/dq.
        efforts[name] = -multiplier
        units[name] = _DRIVERS[named[name]][1]
    return InverseDynamics(system, result, efforts, units, run)
