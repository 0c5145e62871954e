"""``State``: a state of a model (time, coordinates, velocities, accelerations, multipliers),
with accessors by body instead of index arithmetic.

:func:`flexmbd.equilibrium` returns one, :func:`flexmbd.simulate` starts from one
(``initial_state=``), and ``Result.state(k)`` gives the state of a record::

    eq = fm.equilibrium(system)                 # static equilibrium: an EquilibriumState
    eq.elastic_coordinates(arm)                 # q_f of the body 'arm'
    eq.node_displacements(arm, [12])            # (1, 3), body axes
    result = fm.simulate(system, 1.0, 1e-3, initial_state=eq)

A state is immutable; :meth:`State.with_elastic_coordinates` and friends make changed copies.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _core
from ._checks import number
from .errors import InvalidParameterError

Array = NDArray[np.float64]


def _floats(values: ArrayLike, name: str) -> Array:
    """`values` as a new float array; InvalidParameterError naming `name` if they are not
    numbers."""
    try:
        return np.array(values, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(
            f"{name} must be numbers, got {type(values).__name__} ({error})", item=name
        ) from None


def _frozen(values: ArrayLike | None, name: str) -> Array | None:
    if values is None:
        return None
    array = _floats(values, name)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class State:
    """A state of a model.

    Attributes:
        time: s.
        coordinates: q, (coordinate_count,): per body [R (3), Euler parameters (4), q_f].
        velocities: q_dot, (coordinate_count,).
        accelerations: q_dd, (coordinate_count,), or None.
        multipliers: Lagrange multipliers lambda (constraint forces), (constraint_count,), or
            None.
        layout: the model's description (``Model.describe()``), which the accessors use.
        flexible: body index -> the `FlexibleBodyData` of its deformable bodies.
        system_identity: that of the System the model was compiled from: the accessors refuse
            the ids of another system that name other items there (see ``Result``).
        discrete: the discrete variables (``Model.discrete_variables``: the unwrapped angles
            of rotational springs and angle actuators, the actuators' saturation states), or
            None: set from the coordinates (angles in (-pi, pi]). A recorded state carries
            them, so that a run continued from it, and the analyses about it, take a spring
            wound by more than half a turn as wound.

    The accessors take a body as a ``BodyId``, an index or a name, and give the values of
    ``Result``'s accessors of the same name at this one time (without the time axis).
    """

    time: float
    coordinates: Array
    velocities: Array
    accelerations: Array | None = None
    multipliers: Array | None = None
    layout: dict[str, Any] | None = field(default=None, repr=False, compare=False)
    flexible: dict[int, Any] = field(default_factory=dict, repr=False, compare=False)
    #: The identity of the System of the model (`Result.system_identity`), or None.
    system_identity: int | None = field(default=None, repr=False, compare=False)
    #: Whether a run recorded it (`Result.state`), unchanged since: ``simulate`` then takes
    #: the projection of its velocities onto the velocity constraints (the integrator's own
    #: drift, which generalized-alpha leaves within the step's error) as a "continuation"
    #: event, not an initial correction.
    recorded: bool = field(default=False, repr=False, compare=False)
    discrete: Array | None = field(default=None, repr=False, compare=False)

    def discrete_for(self, model: Any) -> Array | None:
        """The state's discrete variables if they are as many as `model` has (a compiled
        Model), else None: then they are set from the coordinates."""
        if self.discrete is None or len(self.discrete) != model.discrete_count:
            return None
        return np.array(self.discrete, dtype=float)

    def __post_init__(self) -> None:
        for name in ("coordinates", "velocities", "accelerations", "multipliers", "discrete"):
            object.__setattr__(self, name, _frozen(getattr(self, name), name))
        object.__setattr__(self, "time", number(self.time, "time"))
        if self.coordinates.shape != self.velocities.shape or self.coordinates.ndim != 1:
            raise InvalidParameterError(
                f"a state needs coordinates and velocities of one length, got "
                f"{self.coordinates.shape} and {self.velocities.shape}",
                item="state",
            )

    @classmethod
    def of_model(cls, model: _core.Model | _core.System, time: float = 0.0) -> State:
        """The model's initial state as given (before the constraints are enforced)."""
        from .system import identity_of

        if isinstance(model, _core.System):
            model = model.compile()
        return cls(
            time,
            model.initial_coordinates,
            model.initial_velocities,
            layout=model.describe(),
            flexible=model.flexible_bodies,
            system_identity=identity_of(model),
        )

    def _view(self) -> Any:
        """A one-record `Result` of this state (its accessors do the lookups)."""
        from .result import Result

        if self.layout is None:
            raise InvalidParameterError(
                "this state has no model layout: make it with State.of_model, "
                "flexmbd.equilibrium or Result.state",
                item="state",
            )
        n = len(self.coordinates)
        zeros = np.zeros((1, 0))
        raw = {
            "time": np.array([self.time]),
            "coordinates": self.coordinates[None, :],
            "velocities": self.velocities[None, :],
            "accelerations": (
                np.zeros((1, n)) if self.accelerations is None else self.accelerations[None, :]
            ),
            "multipliers": zeros if self.multipliers is None else self.multipliers[None, :],
            "constraint_violation": np.zeros(1),
            "statistics": {},
            "reactions": zeros,
            "sensors": zeros,
            "energy": np.zeros((1, 3)),
        }
        view = Result(raw, self.layout, flexible=self.flexible)
        view.system_identity = self.system_identity
        view._described_as = "this state"
        return view

    # Bodies ----------------------------------------------------------------------------
    def position(self, body: object) -> Array:
        """Position of the body frame origin (m, global), (3,)."""
        return self._view().position(body)[0]

    def velocity(self, body: object) -> Array:
        """Velocity of the body frame origin (m/s, global), (3,)."""
        return self._view().velocity(body)[0]

    def euler_parameters(self, body: object) -> Array:
        """Euler parameters [e0, e1, e2, e3], (4,)."""
        return self._view().euler_parameters(body)[0]

    def orientation(self, body: object) -> Array:
        """Rotation matrix of the body frame (columns: body axes in global axes), (3, 3)."""
        return self._view().orientation(body)[0]

    def angular_velocity(self, body: object) -> Array:
        """Angular velocity (rad/s, global axes), (3,)."""
        return self._view().angular_velocity(body)[0]

    def elastic_coordinates(self, body: object) -> Array:
        """Elastic coordinates q_f of a deformable body, (n_f,)."""
        return self._view().elastic_coordinates(body)[0]

    def elastic_velocities(self, body: object) -> Array:
        """Elastic velocities of a deformable body, (n_f,)."""
        return self._view().elastic_velocities(body)[0]

    def node_displacements(self, body: object, nodes: Any = None) -> Array:
        """Elastic displacements of nodes (ids; default all) in body axes (m), (nodes, 3)."""
        return self._view().node_displacements(body, nodes)[0]

    def node_positions(self, body: object, nodes: Any = None) -> Array:
        """Global positions of the deformed nodes (m), (nodes, 3)."""
        return self._view().node_positions(body, nodes)[0]

    def stresses(self, body: object) -> Array:
        """Stresses of a deformable body's solid elements at its nodes (Pa, body axes, Voigt
        order), (nodes, 6); see ``Result.stresses``."""
        return self._view().stresses(body, [0])[0]

    def shell_stresses(self, body: object) -> Array:
        """Stresses of a deformable body's shells at their top, middle and bottom surfaces at
        its nodes (Pa, body axes, Voigt order), (nodes, 3, 6); see ``Result.shell_stresses``."""
        return self._view().shell_stresses(body, [0])[0]

    def section_forces(self, body: object) -> Array:
        """Section resultants [N, V_y, V_z, T, M_y, M_z] at both ends of every beam element of
        a deformable body (N, N m; element axes), (beams, 2, 6); see
        ``Result.section_forces``: the static root moment of an equilibrium."""
        return self._view().section_forces(body, [0])[0]

    def joint_multipliers(self, joint: object) -> Array:
        """The multipliers of a joint's equations (for a driver: its effort), (equations,)."""
        if self.multipliers is None:
            raise InvalidParameterError("this state has no multipliers", item="state")
        return self._view().joint_multipliers(joint)[0]

    # Changed copies --------------------------------------------------------------------
    def _slice(self, body: object, part: str) -> slice:
        b = self._view()._body(body)
        if b["kind"] in ("ground",):
            raise InvalidParameterError(f"the ground has no {part}", item=b["name"])
        o, count = b["offset"], b["count"]
        spans = {
            "position": slice(o, o + 3),
            "euler_parameters": slice(o + 3, o + 7),
            "elastic_coordinates": slice(o + 7, o + count),
        }
        if part != "position" and b["kind"] not in ("rigid", "flexible"):
            raise InvalidParameterError(f"body {b['name']!r} has no {part}", item=b["name"])
        if part == "elastic_coordinates" and b["kind"] != "flexible":
            raise InvalidParameterError(
                f"body {b['name']!r} is not a deformable body", item=b["name"]
            )
        return spans[part]

    def _replaced(self, body: object, part: str, values: ArrayLike, rates: bool) -> State:
        span = self._slice(body, part)
        target = np.array(self.velocities if rates else self.coordinates)
        values = _floats(values, part).ravel()
        if values.shape != target[span].shape:
            raise InvalidParameterError(
                f"{part}: expected {target[span].shape[0]} finite values, got {values.shape}",
                item=part,
            )
        if not np.all(np.isfinite(values)):
            k = int(np.flatnonzero(~np.isfinite(values))[0])
            raise InvalidParameterError(
                f"{part}: expected finite values, entry {k} is {values[k]}", item=part
            )
        target[span] = values
        changed = {"velocities" if rates else "coordinates": target}
        return dataclasses.replace(
            self, **changed, accelerations=None, multipliers=None, recorded=False
        )

    def with_elastic_coordinates(self, body: object, values: ArrayLike) -> State:
        """A copy with the elastic coordinates of a deformable body replaced."""
        return self._replaced(body, "elastic_coordinates", values, rates=False)

    def with_elastic_velocities(self, body: object, values: ArrayLike) -> State:
        """A copy with the elastic velocities of a deformable body replaced."""
        return self._replaced(body, "elastic_coordinates", values, rates=True)

    def with_position(self, body: object, values: ArrayLike) -> State:
        """A copy with the position of a body frame replaced (m, global)."""
        return self._replaced(body, "position", values, rates=False)

    def with_velocity(self, body: object, values: ArrayLike) -> State:
        """A copy with the velocity of a body frame origin replaced (m/s, global)."""
        return self._replaced(body, "position", values, rates=True)


@dataclass(frozen=True)
class EquilibriumState(State):
    """A state of equilibrium (:func:`flexmbd.equilibrium`): the elastic coordinates at rest,
    the other coordinates still or moving as the drivers prescribe; the multipliers are the
    constraint forces that hold it (for a driver: the static driving effort).

    Attributes (besides those of `State`):
        iterations: Newton iterations taken.
        residual: largest |residual| of the equations of motion at the solution.
        stable: whether the equilibrium is stable: True when the stiffness of the equations
            at rest (gravity, springs, elastic and constraint-force terms, centrifugal
            softening under a steady drive) is positive definite in the directions the
            constraints leave free, False when it is negative in some; None where it was
            not determined, also for a neutral equilibrium (zero stiffness in some free
            directions and negative in none: a free body in space, a wheel whose axle no
            force turns), which the stiffness alone does not decide. Under a steady drive
            the stiffness is that of :func:`flexmbd.linearize` about the state (with the
            spin softening of the turning frames; gyroscopic terms are not counted). A
            nonsymmetric stiffness (follower loads) is decided by the eigenvalues of the
            linearized motion: False where some grow (divergence or flutter), True where
            none does; None above 1,000 independent coordinates.
        unstable_directions: the number of free directions of negative stiffness (an
            inverted double pendulum: 2); with a nonsymmetric stiffness, of growing real
            eigenvalues and complex pairs (Beck's column past flutter: 2, one per plane).
        neutral_directions: the number of free directions of zero stiffness (a free rigid
            body without gravity: 6).
    """

    iterations: int = 0
    residual: float = 0.0
    stable: bool | None = None
    unstable_directions: int = 0
    neutral_directions: int = 0
