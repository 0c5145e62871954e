"""Simulation results: time series as NumPy arrays, time first."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._checks import integer, integers_array
from .errors import InvalidModelError, InvalidParameterError, UnknownItemError
from .rotation import angular_velocity, euler_parameters_to_matrix

Array = NDArray[np.float64]

#: The singular of the item lists of a model description, for messages.
_SINGULAR = {"bodies": "body", "joints": "joint", "sensors": "sensor", "markers": "marker"}


#: Element types by what their stresses are.
_SOLIDS = (
    "tet4", "tet10", "hex8", "hex8i", "hex20", "hex20r", "hex27", "wedge6", "wedge15", "wedge18",
    "pyramid5", "pyramid13", "pyramid14",
)  # fmt: skip
_SHELLS = ("quad4", "tri3")
#: Where to look instead, for a body of only these elements.
_STRESS_OF = {
    "beam2": "a beam's stresses are its section forces (section_forces)",
    "quad4": "a shell's stresses are shell_stresses (and stresses, the middle surface)",
    "tri3": "a shell's stresses are shell_stresses (and stresses, the middle surface)",
    "tet4": "a solid's stresses are stresses",
    "tet10": "a solid's stresses are stresses",
    "hex8": "a solid's stresses are stresses",
    "hex8i": "a solid's stresses are stresses",
    "hex20": "a solid's stresses are stresses",
    "hex20r": "a solid's stresses are stresses",
    "hex27": "a solid's stresses are stresses",
    "wedge6": "a solid's stresses are stresses",
    "wedge15": "a solid's stresses are stresses",
    "wedge18": "a solid's stresses are stresses",
    "pyramid5": "a solid's stresses are stresses",
    "pyramid13": "a solid's stresses are stresses",
    "pyramid14": "a solid's stresses are stresses",
}


class _Columns(dict):
    """The columns of `Result.to_dataframe`: a name given twice (a sensor named
    "bob.position" on a body "bob") is refused instead of overwriting the first series."""

    def __setitem__(self, name: str, values: Any) -> None:
        if name in self:
            raise InvalidModelError(
                f"two time series are named {name!r} (the model's names make the columns, e.g. "
                "a sensor 'bob.position' and a body 'bob'): rename one of the items",
                item=name,
            )
        super().__setitem__(name, values)


class Result:
    """Results of :func:`flexmbd.simulate`.

    Arrays are time-major: ``result.time`` has shape (n,), body positions (n, 3), rotation
    matrices (n, 3, 3). Items can be given by their id (``BodyId``, ``JointId``,
    ``SensorId``), their index or their name.

    Attributes:
        time: output times (s), (n,).
        coordinates, velocities, accelerations: generalized coordinates q and their
            derivatives, (n, coordinate_count).
        multipliers: Lagrange multipliers, (n, constraint_count).
        constraint_violation: largest |C(q, t)| at each output, (n,).
        statistics: steps, rejected steps, Newton iterations, factorizations, function
            evaluations (explicit solvers), step sizes.
        events: what happened during the run, in order: dicts with ``time``, ``kind``
            ("initial correction", "redundant constraints", "repartition", "singular
            configuration", "constraint drift", "joint coordinates rebased", "loop rank") and
            ``message``.
        redundancy: the redundant constraints found at the start (dict with ``rows``,
            ``rank``, ``removed_rows``, ``groups`` of rows dependent together, ``joints``
            involved and ``message``), or None.
        success: False if the run stopped on an error (then ``error`` is that error).
        layout: the model description (``Model.describe()``).
    """

    def __init__(
        self,
        raw: dict[str, Any],
        layout: dict[str, Any],
        error: BaseException | None = None,
        flexible: dict[int, Any] | None = None,
    ):
        self.time: Array = raw["time"]
        self.coordinates: Array = raw["coordinates"]
        self.velocities: Array = raw["velocities"]
        self.accelerations: Array = raw["accelerations"]
        self.multipliers: Array = raw["multipliers"]
        self.constraint_violation: Array = raw["constraint_violation"]
        #: The discrete variables per record (unwrapped spring and actuator angles, the
        #: actuators' saturation states), (n, discrete variables); (n, 0) for results files
        #: written before they were recorded.
        self.discrete: Array = np.asarray(
            raw.get("discrete", np.zeros((len(raw["time"]), 0))), dtype=float
        )
        self.statistics: dict[str, float] = dict(raw["statistics"])
        self.events: list[dict[str, Any]] = list(raw.get("events", []))
        self.redundancy: dict[str, Any] | None = raw.get("redundancy")
        self.layout = layout
        self.error = error
        self.success = error is None
        self._reactions: Array = raw["reactions"]
        self._sensors: Array = raw["sensors"]
        self._energy: Array = raw["energy"]
        #: Deformable bodies: body index -> their FlexibleBodyData (for node outputs).
        self.flexible: dict[int, Any] = dict(flexible or {})
        #: The results file the run wrote (:func:`flexmbd.simulate` with ``results_file``), or
        #: None.
        self.file: Any = None
        #: The identity of the System the run's model was compiled from (None: unknown, as
        #: for a results file read back): the ids of another system naming other items here
        #: are refused.
        self.system_identity: int | None = None

    def __len__(self) -> int:
        return len(self.time)

    def _record(self, name: str) -> Array:
        """The record array `name` as :func:`flexmbd.simulate` delivered it (one row per
        output): the public arrays, and the raw reactions, sensors and energies."""
        raw = {"reactions": self._reactions, "sensors": self._sensors, "energy": self._energy}
        return raw[name] if name in raw else getattr(self, name)

    def __repr__(self) -> str:
        status = "complete" if self.success else f"stopped: {type(self.error).__name__}"
        if len(self.time) == 0:
            return f"Result(no records, {status})"
        return (
            f"Result({len(self.time)} records, t = {self.time[0]:g} .. {self.time[-1]:g} s, "
            f"{self.statistics.get('steps', 0)} steps, {status})"
        )

    def state(self, index: int = -1) -> Any:
        """The :class:`flexmbd.State` of record `index` (default the last): start another run
        from it with ``simulate(..., initial_state=result.state())``."""
        from .state import State

        if len(self.time) == 0:
            raise InvalidParameterError("the result has no records", item="result")
        index = integer(index, "index")
        if not -len(self.time) <= index < len(self.time):
            raise InvalidParameterError(
                f"record index {index} is out of range (the result has {len(self.time)} records)",
                item="index",
            )
        count = int(self.layout.get("discrete_count", 0)) if self.layout else 0
        recorded = self.discrete.shape[1:] == (count,) and count > 0
        return State(
            float(self.time[index]),
            self.coordinates[index],
            self.velocities[index],
            self.accelerations[index],
            self.multipliers[index],
            layout=self.layout,
            flexible=self.flexible,
            system_identity=self.system_identity,
            recorded=True,
            discrete=self.discrete[index] if recorded else None,
        )

    # Energies -------------------------------------------------------------------------
    @property
    def kinetic_energy(self) -> Array:
        """Kinetic energy (J), (n,)."""
        return self._energy[:, 0]

    @property
    def potential_energy(self) -> Array:
        """Potential energy of gravity, springs and elastic deformation (J), (n,)."""
        return self._energy[:, 1]

    @property
    def strain_energy(self) -> Array:
        """Strain energy of the deformable bodies (J), (n,), part of the potential energy:
        1/2 q_f^T K_ff q_f and the nonlinear strain of the geometric stiffness. NaN for
        results files written before it was recorded."""
        if self._energy.shape[1] < 3:
            return np.full(len(self._energy), np.nan)
        return self._energy[:, 2]

    @property
    def nonconservative_power(self) -> Array:
        """Power (W), (n,), of the forces no potential energy accounts for: point forces,
        torques, joint actuators and callback forces (their whole power Q . q_dot), the
        dampers of the spring-dampers and the structural damping of the deformable bodies
        (negative: dissipated). The drivers' power is apart
        (:func:`flexmbd.quantities.driver_power`). NaN for results files written before it
        was recorded."""
        if self._energy.shape[1] < 4:
            return np.full(len(self._energy), np.nan)
        return self._energy[:, 3]

    @property
    def total_energy(self) -> Array:
        """Kinetic plus potential energy (J), (n,)."""
        return self._energy[:, 0] + self._energy[:, 1]

    # Lookups ---------------------------------------------------------------------------
    #: What the lookups' errors call this (a `State`'s one-record view: "this state").
    _described_as = "this result"

    def _lookup(self, kind: str, item: object, id_type: type) -> tuple[int, dict[str, Any]]:
        entries = self.layout[kind]
        singular = _SINGULAR.get(kind, kind)
        if isinstance(item, id_type):
            from .system import stray_id, stray_id_error

            def name_here(item: Any) -> str | None:
                return entries[item.index]["name"] if item.index < len(entries) else None

            if stray_id(self.system_identity, item, name_here) is not None:
                raise stray_id_error(item, self._described_as, name_here(item))
            index = item.index  # type: ignore[attr-defined]
        elif isinstance(item, bool | np.bool_):  # (True was body 1)
            raise UnknownItemError(
                f"expected a {id_type.__name__}, an index or a name, got {item!r}", item=str(item)
            )
        elif isinstance(item, int | np.integer):
            index = int(item)
        elif isinstance(item, str):
            names = [e["name"] for e in entries]
            if item not in names:
                raise UnknownItemError(f"no {singular} named {item!r}; known: {names}", item=item)
            index = names.index(item)
        else:  # (a float, or another kind's id: the item named)
            raise UnknownItemError(
                f"expected a {id_type.__name__}, an index or a name, got {item!r}",
                item=str(item),
            )
        if not 0 <= index < len(entries):
            raise UnknownItemError(
                f"{singular} {index} does not exist (the model has {len(entries)} {kind})",
                item=str(item),
            )
        return index, entries[index]

    def _body(self, body: object) -> dict[str, Any]:
        _, entry = self._lookup("bodies", body, _core.BodyId)
        return entry

    # Bodies ----------------------------------------------------------------------------
    def position(self, body: object) -> Array:
        """Position of the body frame origin (m, global), (n, 3)."""
        b = self._body(body)
        if b["kind"] == "ground":
            return np.zeros((len(self.time), 3))
        return self.coordinates[:, b["offset"] : b["offset"] + 3]

    def velocity(self, body: object) -> Array:
        """Velocity of the body frame origin (m/s, global), (n, 3)."""
        b = self._body(body)
        if b["kind"] == "ground":
            return np.zeros((len(self.time), 3))
        return self.velocities[:, b["offset"] : b["offset"] + 3]

    def euler_parameters(self, body: object) -> Array:
        """Euler parameters [e0, e1, e2, e3] of a rigid or deformable body, (n, 4)."""
        b = self._body(body)
        if b["kind"] not in ("rigid", "flexible"):
            p = np.zeros((len(self.time), 4))
            p[:, 0] = 1.0
            return p
        return self.coordinates[:, b["offset"] + 3 : b["offset"] + 7]

    def orientation(self, body: object) -> Array:
        """Rotation matrix of the body frame (columns: body axes in global axes), (n, 3, 3)."""
        return euler_parameters_to_matrix(self.euler_parameters(body))

    def angular_velocity(self, body: object) -> Array:
        """Angular velocity (rad/s, global axes), (n, 3): w = 2 E(p) p_dot."""
        b = self._body(body)
        if b["kind"] not in ("rigid", "flexible"):
            return np.zeros((len(self.time), 3))
        o = b["offset"]
        return angular_velocity(
            self.coordinates[:, o + 3 : o + 7], self.velocities[:, o + 3 : o + 7]
        )

    # Deformable bodies -----------------------------------------------------------------
    def _flexible(self, body: object) -> tuple[dict[str, Any], Any]:
        index, b = self._lookup("bodies", body, _core.BodyId)
        if b["kind"] != "flexible" or index not in self.flexible:
            raise UnknownItemError(f"body {b['name']!r} is not a deformable body", item=b["name"])
        return b, self.flexible[index]

    def elastic_coordinates(self, body: object) -> Array:
        """Elastic coordinates q_f of a deformable body (nodal or modal), (n, n_f)."""
        b, _ = self._flexible(body)
        return self.coordinates[:, b["offset"] + 7 : b["offset"] + b["count"]]

    def elastic_velocities(self, body: object) -> Array:
        """Elastic velocities of a deformable body, (n, n_f)."""
        b, _ = self._flexible(body)
        return self.velocities[:, b["offset"] + 7 : b["offset"] + b["count"]]

    def node_displacements(self, body: object, nodes: Any = None) -> Array:
        """Elastic displacements of nodes relative to the body frame, in body axes (m):
        (n, nodes, 3). `nodes`: node ids of the mesh (default: all nodes)."""
        from .system import elastic_basis

        _, data = self._flexible(body)
        index = self._node_indices(data, nodes)
        d = data.dofs_per_node
        rows = (index[:, None] * d + np.arange(3)[None, :]).ravel()
        basis = elastic_basis(data)[rows]
        q_f = self.elastic_coordinates(body)
        return np.asarray(basis @ q_f.T).T.reshape(len(self.time), len(index), 3)

    def node_positions(self, body: object, nodes: Any = None) -> Array:
        """Global positions of the deformed nodes r = R + A (u0 + u_f) (m): (n, nodes, 3)."""
        _, data = self._flexible(body)
        index = self._node_indices(data, nodes)
        local = data.nodes[index][None, :, :] + self.node_displacements(body, nodes)
        rot = self.orientation(body)
        return self.position(body)[:, None, :] + np.einsum("tij,tnj->tni", rot, local)

    def _nodal_displacements(self, body: object, records: Any) -> Array:
        from .system import elastic_basis

        _, data = self._flexible(body)
        q_f = self.elastic_coordinates(body)
        q_f = q_f if records is None else q_f[self._record_indices(records)]
        return np.asarray(elastic_basis(data) @ q_f.T).T

    def _record_indices(self, records: Any) -> NDArray[np.int64]:
        """Record indices (negative from the end) checked against the records there are."""
        index = np.atleast_1d(integers_array(records, "records"))
        if index.ndim != 1:  # ([[0, 1]] reached scipy as "could not interpret dimensions")
            raise InvalidParameterError(
                f"records: one list of record indices, got an array of shape {index.shape}",
                item="records",
            )
        index = index.astype(np.int64)  # (an empty list: no records, not a float array)
        count = len(self.time)
        outside = index[(index < -count) | (index >= count)]
        if outside.size:
            raise InvalidParameterError(
                f"records: {int(outside[0])} is not a record index ({self._described_as} has "
                f"{count} records: 0 to {count - 1}, or -{count} to -1 from the end)",
                item="records",
            )
        return index

    def _with_elements(self, body: object, kinds: tuple[str, ...], what: str) -> None:
        """InvalidParameterError naming the body when it has no elements of `kinds`."""
        b, data = self._flexible(body)
        if not any(len(data.elements.get(kind, ())) for kind in kinds):
            present = ", ".join(kind for kind in data.elements if len(data.elements[kind]))
            others = f"its elements are {present}" if present else "it has no elements"
            raise InvalidParameterError(
                f"body {b['name']!r} has no {what} ({others}); "
                + _STRESS_OF.get(
                    present,
                    "stresses (solids, shells' middle surface), shell_stresses (shells) and "
                    "section_forces (beams) give each kind's",
                ),
                item=b["name"],
            )

    def stresses(self, body: object, records: Any = None) -> Array:
        """Stresses of the solid elements (and the middle surface of shells) of a deformable
        body averaged at its nodes (Pa, body axes, Voigt order xx, yy, zz, yz, xz, xy):
        (n, nodes, 6), for all records or the given record indices. See
        :mod:`flexmbd.fe.stress`."""
        from .fe.stress import recover_stresses

        self._with_elements(body, _SOLIDS + _SHELLS, "solid or shell elements")
        _, data = self._flexible(body)
        return recover_stresses(data, self._nodal_displacements(body, records))[0]

    def von_mises(self, body: object, records: Any = None) -> Array:
        """Von Mises stress at the nodes of a deformable body (Pa): (n, nodes), for all records
        or the given record indices; of its solid elements, and at the nodes of shells the
        largest of their top, middle and bottom surfaces. See
        :func:`flexmbd.fe.stress.nodal_von_mises`."""
        from .fe.stress import nodal_von_mises

        self._with_elements(body, _SOLIDS + _SHELLS, "solid or shell elements")
        _, data = self._flexible(body)
        displacements = np.atleast_2d(self._nodal_displacements(body, records))
        return nodal_von_mises(data, displacements)

    def shell_stresses(self, body: object, records: Any = None) -> Array:
        """Stresses of the shell elements of a deformable body at their top, middle and bottom
        surfaces, averaged at its nodes (Pa, body axes, Voigt order): (n, nodes, 3, 6). See
        :func:`flexmbd.fe.stress.shell_stresses`."""
        from .fe.stress import shell_stresses

        self._with_elements(body, _SHELLS, "shell elements")
        _, data = self._flexible(body)
        return shell_stresses(data, np.atleast_2d(self._nodal_displacements(body, records)))

    def section_forces(self, body: object, records: Any = None) -> Array:
        """Section resultants [N, V_y, V_z, T, M_y, M_z] (N, N m; element axes; tension
        positive) at both ends of every beam element of a deformable body: (n, beams, 2, 6)."""
        from .fe.stress import recover_stresses

        self._with_elements(body, ("beam2",), "beam elements")
        _, data = self._flexible(body)
        return recover_stresses(data, self._nodal_displacements(body, records))[1]

    def deflection(self, body: object, node: int, chord: tuple[int, int] | None = None) -> Array:
        """Deflection of a node of a deformable body (m, body axes): (n, 3). Without `chord`,
        its elastic displacement relative to the body frame; with `chord=(a, b)` (node ids),
        its distance vector from the straight line through the deformed nodes a and b (the
        deflection from the chord, exact for large deformations)."""
        _, data = self._flexible(body)
        node = integer(node, "node")
        if chord is None:
            return self.node_displacements(body, [node])[:, 0]
        if isinstance(chord, str) or not hasattr(chord, "__len__") or len(chord) != 2:
            raise InvalidParameterError(
                f"chord must be two node ids (a, b), got {chord!r}", item="chord"
            )
        ends = [integer(chord[0], "chord"), integer(chord[1], "chord")]
        if ends[0] == ends[1]:
            raise InvalidParameterError(
                f"chord ({ends[0]}, {ends[1]}): the chord needs two different nodes",
                item="chord",
            )
        ids = [*ends, node]
        index = self._node_indices(data, ids)
        x = data.nodes[index][None, :, :] + self.node_displacements(body, ids)
        d = x[:, 1] - x[:, 0]
        d /= np.linalg.norm(d, axis=1)[:, None]
        r = x[:, 2] - x[:, 0]
        return r - np.sum(r * d, axis=1)[:, None] * d

    @staticmethod
    def _node_indices(data: Any, nodes: Any) -> NDArray[np.int64]:
        if nodes is None:
            return np.arange(len(data.nodes))
        ids = np.asarray(data.node_ids)
        given = np.atleast_1d(np.asarray(nodes, dtype=object))
        if given.ndim != 1:
            raise InvalidParameterError(
                f"nodes must be a node id or a list of node ids, got an array of shape "
                f"{given.shape}",
                item="nodes",
            )
        wanted = [integer(k, "nodes") for k in given]
        lookup = {int(k): i for i, k in enumerate(ids)}
        missing = [k for k in wanted if k not in lookup]
        if missing:
            raise UnknownItemError(f"no nodes with ids {missing} in the body", item=str(missing))
        return np.array([lookup[int(k)] for k in wanted], dtype=np.int64)

    # Joints ----------------------------------------------------------------------------
    def reaction(self, joint: object) -> tuple[Array, Array]:
        """Force (N) and torque (N m) that the joint exerts on the body of its second marker,
        about that marker's origin, in that marker's axes: two (n, 3) arrays. For a driver,
        the torque (angle driver) or force (translation driver) component along the z axis
        is the driving effort."""
        index, _ = self._lookup("joints", joint, _core.JointId)
        return self._reactions[:, index, :3], self._reactions[:, index, 3:]

    def reaction_force(self, joint: object) -> Array:
        """Reaction force of :meth:`reaction`, (n, 3)."""
        return self.reaction(joint)[0]

    def reaction_torque(self, joint: object) -> Array:
        """Reaction torque of :meth:`reaction`, (n, 3)."""
        return self.reaction(joint)[1]

    def joint_multipliers(self, joint: object) -> Array:
        """Lagrange multipliers of a joint's equations, (n, equations)."""
        _, j = self._lookup("joints", joint, _core.JointId)
        return self.multipliers[:, j["row"] : j["row"] + len(j["equations"])]

    def driver_effort(self, driver: object) -> Array:
        """The effort of an angle driver (torque, N m) or a translation driver (force, N) on
        the joint coordinate it prescribes, acting on its second marker's body: minus its
        multiplier, (n,). (On markers of deformable bodies' nodes the angle driver's effort
        differs from it by the square of the elastic rotation, which
        :func:`flexmbd.inverse_dynamics` takes into account.) Raises `InvalidParameterError`
        for a joint that is not a driver."""
        _, j = self._lookup("joints", driver, _core.JointId)
        if j["type"] not in ("angle driver", "translation driver"):
            raise InvalidParameterError(
                f"joint {j['name']!r} is a {j['type']} joint, not a driver", item=j["name"]
            )
        return -self.multipliers[:, j["row"]]

    def actuator_effort(self, actuator: object) -> Array:
        """The effort of the joint actuator `actuator` (the ForceId `add_joint_actuator`
        returned, or its name; its torque, N m, or force, N, after the limit), (n,): the
        sensor "`name` effort" it records ("actuator <k> effort" when unnamed). Raises
        `UnknownItemError` naming the actuators when `actuator` is none of them."""
        sensors = {s["name"] for s in self.layout["sensors"]}
        if isinstance(actuator, _core.ForceId):
            index, entry = self._lookup("forces", actuator, _core.ForceId)
            if entry["type"] != "joint actuator":
                raise UnknownItemError(
                    f"force {entry['name']!r} is a {entry['type']}, not a joint actuator",
                    item=str(entry["name"]),
                )
            named = f"{entry['name']} effort" in sensors
            actuator = entry["name"] if named else f"actuator {index}"
        if f"{actuator} effort" not in sensors:
            actuators = sorted(
                name[: -len(" effort")] for name in sensors if name.endswith(" effort")
            )
            joints = {j["name"]: j["type"] for j in self.layout["joints"]}
            what = (
                f"joint {actuator!r} is a {joints[actuator]} joint without an actuator"
                if actuator in joints
                else f"no actuator named {actuator!r}"
            )
            raise UnknownItemError(
                f"{what} (actuators: {', '.join(map(repr, actuators)) or 'none'}); the effort "
                "of a driver is driver_effort",
                item=str(actuator),
            )
        return self.sensor(f"{actuator} effort")[:, 0]

    # Sensors ---------------------------------------------------------------------------
    def sensor(self, sensor: object) -> Array:
        """Values of a sensor: (n, 3), (n, 3, 3) for an orientation, (n, 1) for an actuator's
        effort (the sensor "NAME effort")."""
        _, s = self._lookup("sensors", sensor, _core.SensorId)
        values = self._sensors[:, s["offset"] : s["offset"] + s["size"]]
        if s["size"] == 9:
            return values.reshape(-1, 3, 3)
        return values

    # Tables ----------------------------------------------------------------------------
    def _columns(self) -> dict[str, Array]:
        """Named time series (SI units): body positions, velocities and Euler parameters,
        elastic coordinates, joint reactions and multipliers, sensors, energies and the
        constraint violation."""
        columns = _Columns()
        for body in self.layout["bodies"]:
            if body["kind"] == "ground":
                continue
            name = body["name"]
            for k, axis in enumerate("xyz"):
                columns[f"{name}.position.{axis}"] = self.position(name)[:, k]
            for k, axis in enumerate("xyz"):
                columns[f"{name}.velocity.{axis}"] = self.velocity(name)[:, k]
            if body["kind"] != "point_mass":
                for k in range(4):
                    columns[f"{name}.euler_parameter.{k}"] = self.euler_parameters(name)[:, k]
            if body["kind"] == "flexible":
                elastic = self.elastic_coordinates(name)
                for k in range(elastic.shape[1]):
                    columns[f"{name}.elastic.{k}"] = elastic[:, k]
        for joint in self.layout["joints"]:
            force, torque = self.reaction(joint["name"])
            for k, axis in enumerate("xyz"):
                columns[f"{joint['name']}.reaction_force.{axis}"] = force[:, k]
            for k, axis in enumerate("xyz"):
                columns[f"{joint['name']}.reaction_torque.{axis}"] = torque[:, k]
            multipliers = self.joint_multipliers(joint["name"])
            for k, equation in enumerate(joint["equations"]):
                columns[f"{joint['name']}.multiplier.{equation}"] = multipliers[:, k]
        labels = self._sensor_labels()
        for k, label in enumerate(labels):
            columns[label] = self._sensors[:, k]
        columns["kinetic_energy"] = self.kinetic_energy
        columns["potential_energy"] = self.potential_energy
        columns["strain_energy"] = self.strain_energy
        columns["nonconservative_power"] = self.nonconservative_power
        columns["constraint_violation"] = self.constraint_violation
        return columns

    def _sensor_labels(self) -> list[str]:
        """A label per sensor value: "tip.x" of a vector, "tip.xy" (row x, column y) of an
        orientation matrix, the name alone of a scalar (an actuator's "servo effort"; it was
        "servo effort.x")."""
        labels = [""] * self._sensors.shape[1]
        for sensor in self.layout["sensors"]:
            size = sensor["size"]
            if size == 1:
                labels[sensor["offset"]] = sensor["name"]
                continue
            parts = [a + b for a in "xyz" for b in "xyz"] if size == 9 else list("xyz")[:size]
            if len(parts) != size:
                parts = [str(k) for k in range(size)]
            for k, part in enumerate(parts):
                labels[sensor["offset"] + k] = f"{sensor['name']}.{part}"
        return labels

    def to_dataframe(self) -> Any:
        """The named time series as a pandas DataFrame indexed by time (s); columns like
        ``"crank.position.x"``, ``"bearing.reaction_force.y"``, ``"rod.elastic.3"``,
        ``"tip.z"`` (a sensor), ``"kinetic_energy"``, ``"strain_energy"``,
        ``"nonconservative_power"``; ``frame.attrs["success"]`` is False for a failed or
        interrupted run (its records end early). Needs pandas (``pip install flexmbd[data]``)."""
        import pandas as pd

        frame = pd.DataFrame(self._columns(), index=pd.Index(self.time, name="time"))
        frame.attrs["units"] = "SI (m, kg, s, rad, N, N m, J, W)"
        # (a failed or interrupted run's records end before its end time)
        frame.attrs["success"] = self.success
        return frame

    def to_xarray(self) -> Any:
        """The results as an xarray Dataset on the dimension ``time``: the generalized
        coordinates, velocities, accelerations and multipliers as arrays (dimensions
        ``coordinate`` and ``constraint``, named), the reactions (``joint``, ``component``),
        sensors (dimension ``sensor_value``, labelled ``"tip.x"``), energies and the constraint
        violation. Needs xarray."""
        import xarray as xr

        coordinate_names = [""] * self.coordinates.shape[1]
        for body in self.layout["bodies"]:
            for k in range(body["count"]):
                coordinate_names[body["offset"] + k] = f"{body['name']}[{k}]"
        constraint_names = [""] * self.multipliers.shape[1]
        for joint in self.layout["joints"]:
            for k, equation in enumerate(joint["equations"]):
                if joint["row"] + k < len(constraint_names):
                    constraint_names[joint["row"] + k] = f"{joint['name']}: {equation}"
        for k, name in enumerate(constraint_names):
            constraint_names[k] = name or f"normalization {k}"
        joints = [joint["name"] for joint in self.layout["joints"]]
        components = ["force x", "force y", "force z", "torque x", "torque y", "torque z"]
        data = {
            "coordinates": (("time", "coordinate"), self.coordinates),
            "velocities": (("time", "coordinate"), self.velocities),
            "accelerations": (("time", "coordinate"), self.accelerations),
            "multipliers": (("time", "constraint"), self.multipliers),
            "reactions": (("time", "joint", "component"), self._reactions),
            "sensors": (("time", "sensor_value"), self._sensors),
            "kinetic_energy": (("time",), self.kinetic_energy),
            "potential_energy": (("time",), self.potential_energy),
            "strain_energy": (("time",), self.strain_energy),
            "nonconservative_power": (("time",), self.nonconservative_power),
            "constraint_violation": (("time",), self.constraint_violation),
        }
        coords = {
            "time": self.time,
            "coordinate": coordinate_names,
            "constraint": constraint_names,
            "joint": joints,
            "component": components,
            "sensor_value": self._sensor_labels(),
        }
        dataset = xr.Dataset(data, coords=coords)
        dataset["time"].attrs["units"] = "s"
        dataset.attrs["units"] = "SI (m, kg, s, rad, N, N m, J)"
        dataset.attrs["success"] = int(self.success)
        return dataset
