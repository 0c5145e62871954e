"""The values of the quantities the plots know (:mod:`flexmbd.plotting`), as numbers, and
reductions of them over time: what a study (:class:`flexmbd.Study`) records per case.

:func:`quantity_values` gives a quantity's time history with a label per component;
:func:`output_value` evaluates an output specification::

    max-abs(deflection:rod:5[y])     largest |u_y| of node 5 of body "rod" over the run
    max(stress:rod[bending])         largest bending moment in the rod
    final(position:slider[x])        x of the slider at the end
    series(sensor:tip[1])            the whole time history (a "time" dimension in a study)

Reductions: ``max``, ``min``, ``max-abs``, ``mean``, ``rms``, ``initial``, ``final`` and
``series``. A component is an index or a label (``x``, ``y``, ``z``, ``total``, ``bending``,
...), or a vector's length: ``magnitude`` (of x, y, z), ``force`` and ``torque`` (of a
reaction's fx, fy, fz and tx, ty, tz); a quantity of several components needs one::

    max(deflection:rod:5[magnitude])  largest |u| of node 5 of body "rod" over the run
    max(reaction:hinge[force])        largest force of joint "hinge"
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._checks import id_text
from .errors import InvalidParameterError, UnknownItemError

Array = NDArray[np.float64]

#: Quantity kinds that take no item.
PLAIN_QUANTITIES = ("energy", "drift", "violation", "reactions")
#: Quantity kinds that take an item (a name or an index) after a colon.
ITEM_QUANTITIES = (
    "position",
    "velocity",
    "angular-velocity",
    "elastic",
    "deflection",
    "stress",
    "reaction",
    "sensor",
)
#: Reductions over time of an output specification.
REDUCTIONS = ("max", "min", "max-abs", "mean", "rms", "initial", "final", "series")

_AXES = ["x", "y", "z"]
_SPEC = re.compile(
    r"^\s*(?:(?P<reduction>[a-z-]+)\()?(?P<quantity>[^\[\]()]+?)"
    r"(?:\[(?P<component>[^\]]+)\])?(?(reduction)\))\s*$"
)


#: Components that are the length of a vector of other components: the `magnitude` of a
#: position, velocity, deflection or sensor (x, y, z), the `force` and `torque` of a reaction.
MAGNITUDES = {
    "magnitude": ("x", "y", "z"),
    "force": ("fx", "fy", "fz"),
    "torque": ("tx", "ty", "tz"),
}


#: SI unit of each component of a quantity kind (by label; "*" for every component).
#: Elastic coordinates mix lengths and slopes (nodal) or are modal amplitudes: no unit.
UNITS: dict[str, dict[str, str]] = {
    "energy": {"*": "J"},
    "drift": {"*": "J"},
    "violation": {"*": "m or rad"},
    "reactions": {"*": "N"},
    "position": {"*": "m"},
    "velocity": {"*": "m/s"},
    "angular-velocity": {"*": "rad/s"},
    "elastic": {"*": ""},
    "deflection": {"*": "m"},
    "stress": {"von-mises": "Pa", "axial": "N", "bending": "N m"},
    "reaction": {"fx": "N", "fy": "N", "fz": "N", "tx": "N m", "ty": "N m", "tz": "N m"},
}

#: SI unit of the values of a sensor, by its quantity (as in the model's description).
SENSOR_UNITS = {
    "position": "m",
    "velocity": "m/s",
    "acceleration": "m/s^2",
    "orientation": "",
    "angular_velocity": "rad/s",
    "angular velocity": "rad/s",
    "angular_acceleration": "rad/s^2",
    "angular acceleration": "rad/s^2",
    "actuator torque (N m)": "N m",
    "actuator force (N)": "N",
}

#: SI unit of the outputs of a model file (``outputs:``), by their quantity.
OUTPUT_UNITS = {
    "position": "m",
    "velocity": "m/s",
    "orientation": "",
    "euler_parameters": "",
    "angular_velocity": "rad/s",
    "elastic_coordinates": "",
    "elastic_velocities": "",
    "node_displacements": "m",
    "node_positions": "m",
    "deflection": "m",
    "stresses": "Pa",
    "section_forces": "N, N m",
    "reaction_force": "N",
    "reaction_torque": "N m",
    "multipliers": "",
    "kinetic_energy": "J",
    "potential_energy": "J",
    "strain_energy": "J",
    "total_energy": "J",
    "constraint_violation": "m or rad",
}

#: How a time history is summed up in one line, by the kind of quantity:
#: "range" (positions, orientations: where it went, per component), "magnitude" (vectors
#: whose size matters: the largest |v| and when), "extremes" (signed scalars: smallest and
#: largest, and when), "largest" (the largest value, e.g. a constraint violation).
SUMMARIES = {
    "position": "range",
    "orientation": "range",
    "euler_parameters": "range",
    "node_positions": "range",
    "velocity": "magnitude",
    "angular_velocity": "magnitude",
    "acceleration": "magnitude",
    "angular_acceleration": "magnitude",
    "node_displacements": "magnitude",
    "deflection": "magnitude",
    "reaction_force": "magnitude",
    "reaction_torque": "magnitude",
    "elastic_coordinates": "largest-abs",
    "elastic_velocities": "largest-abs",
    "stresses": "largest-abs",
    "section_forces": "largest-abs",
    "multipliers": "largest-abs",
    "kinetic_energy": "extremes",
    "potential_energy": "extremes",
    "strain_energy": "extremes",
    "total_energy": "extremes",
    "constraint_violation": "largest",
}


def unit_of(kind: str, label: str | None = None) -> str:
    """The SI unit of component `label` of a quantity kind of this module ("" if it has
    none); kind "sensor:QUANTITY" for a sensor of that quantity."""
    if kind.startswith("sensor:"):
        return SENSOR_UNITS.get(kind.partition(":")[2], "")
    units = UNITS.get(kind, {})
    return units.get(label or "*", units.get("*", ""))


def with_unit(text: str, unit: str) -> str:
    """`text (unit)`, or `text (-)` for a quantity without a unit."""
    return f"{text} ({unit or '-'})"


def summarize(values: Any, times: Any, quantity: str | None, unit: str) -> str:
    """One line that sums up a time history (records first) of a quantity (an output
    quantity of a model file, or a sensor quantity), with its unit: see :data:`SUMMARIES`."""
    values = np.asarray(values, dtype=float).reshape(len(times), -1)
    times = np.asarray(times, dtype=float)
    kind = SUMMARIES.get(str(quantity), "extremes" if values.shape[1] == 1 else "magnitude")
    u = f" {unit}" if unit else ""
    # A history that does not change but by round-off (a static run) has no time of its
    # largest value: its round-off picked one.
    spread = np.ptp(values, axis=0) if len(values) else np.zeros(values.shape[1])
    constant = len(values) > 1 and bool(
        np.all(spread <= 1e-9 * float(np.max(np.abs(values), initial=0.0)))
    )

    def largest(what: str, value: float, k: int) -> str:
        if constant:
            return f"{what} {value:.6g}{u} throughout"
        return f"largest {what} {value:.6g}{u} at t = {times[k]:.6g} s".replace("  ", " ")

    if kind == "range":
        # Round-off of components that stay at zero (a planar model's z: 1e-60) shown as 0.
        scale = float(np.max(np.abs(values), initial=0.0))
        values = np.where(np.abs(values) <= 1e-12 * scale, 0.0, values)
        labels = _AXES if values.shape[1] == 3 else [str(k) for k in range(values.shape[1])]
        shown = [
            f"{label} {values[0, k]:.6g} -> {values[-1, k]:.6g} (from {values[:, k].min():.6g}"
            f" to {values[:, k].max():.6g})"
            for k, label in enumerate(labels[:4])
        ]
        more = " ..." if values.shape[1] > 4 else ""
        return "; ".join(shown) + more + u
    if kind == "magnitude" and values.shape[1] % 3 == 0:
        # Vectors (several for node outputs): the largest length of any of them.
        size = np.linalg.norm(values.reshape(len(times), -1, 3), axis=2).max(axis=1)
        k = int(np.argmax(size))
        return largest("magnitude", size[k], k)
    if kind == "extremes" and values.shape[1] == 1:
        if constant:
            return f"{values[0, 0]:.6g}{u} throughout"
        low, high = int(np.argmin(values[:, 0])), int(np.argmax(values[:, 0]))
        return (
            f"smallest {values[low, 0]:.6g}{u} at t = {times[low]:.6g} s, largest "
            f"{values[high, 0]:.6g}{u} at t = {times[high]:.6g} s"
        )
    if kind == "largest":
        k = int(np.argmax(values.max(axis=1)))
        return largest("", values[k].max(), k).strip()
    size = np.abs(values).max(axis=1)
    k = int(np.argmax(size))
    return largest("|value|", size[k], k)


def resolve_item(result: Any, kind: str, text: str) -> object:
    """A body, joint or sensor (`kind` "bodies", "joints", "sensors") given by name, or else
    by index; UnknownItemError naming the known items otherwise."""
    entries = result.layout[kind]
    names = [e["name"] for e in entries]
    if text in names:
        return text
    if re.fullmatch(r"\d+", text) and int(text) < len(entries):
        return int(text)
    singular = {"bodies": "body", "joints": "joint", "sensors": "sensor"}[kind]
    raise UnknownItemError(f"no {singular} named {text!r}; known: {names}", item=text)


def quantity_values(result: Any, quantity: str) -> tuple[Array, list[str]]:
    """The time history of `quantity` (records x components) and a label per component."""
    kind, _, rest = quantity.strip().partition(":")
    if kind in PLAIN_QUANTITIES and not rest:
        return _plain(result, kind)
    if kind not in ITEM_QUANTITIES or not rest:
        known = ", ".join([*PLAIN_QUANTITIES, *(f"{k}:ITEM" for k in ITEM_QUANTITIES)])
        raise InvalidParameterError(f"unknown quantity {quantity!r}; known: {known}", item=quantity)
    if kind == "reaction":
        joint = resolve_item(result, "joints", rest)
        values = np.hstack([result.reaction_force(joint), result.reaction_torque(joint)])
        return values, ["fx", "fy", "fz", "tx", "ty", "tz"]
    if kind == "sensor":
        values = np.asarray(result.sensor(resolve_item(result, "sensors", rest)))
        values = values.reshape(len(result.time), -1)
        labels = _AXES if values.shape[1] == 3 else [str(k) for k in range(values.shape[1])]
        return values, list(labels)
    body_text, _, node_text = rest.partition(":")
    body = resolve_item(result, "bodies", body_text)
    if kind == "deflection":
        return _deflection(result, body, node_text)
    if node_text:
        raise InvalidParameterError(f"{kind} takes one item, got {rest!r}", item=quantity)
    if kind == "stress":
        return _stress(result, body)
    values = {
        "position": result.position,
        "velocity": result.velocity,
        "angular-velocity": result.angular_velocity,
        "elastic": result.elastic_coordinates,
    }[kind](body)
    labels = [f"q_f[{k}]" for k in range(values.shape[1])] if kind == "elastic" else _AXES
    return np.asarray(values), list(labels)


def _plain(result: Any, kind: str) -> tuple[Array, list[str]]:
    if kind == "energy":
        values = [result.kinetic_energy, result.potential_energy, result.total_energy]
        return np.column_stack(values), ["kinetic", "potential", "total"]
    if kind == "drift":
        total = np.asarray(result.total_energy)
        drift = total - total[0] if len(total) else total
        return drift[:, None], ["drift"]
    if kind == "violation":
        return np.asarray(result.constraint_violation)[:, None], ["violation"]
    joints = [j["name"] for j in result.layout["joints"]]
    values = [np.linalg.norm(result.reaction_force(j), axis=1) for j in joints]
    return np.column_stack(values) if values else np.zeros((len(result.time), 0)), joints


def _deflection(result: Any, body: object, node_text: str) -> tuple[Array, list[str]]:
    """u_x, u_y, u_z of a node (its id, or the node that moves most) and the largest |u|."""
    data = deformable(result, body)[2]
    u = result.node_displacements(body)
    magnitude = np.linalg.norm(u, axis=2)
    if node_text:
        if not re.fullmatch(r"-?\d+", node_text):
            raise InvalidParameterError(f"node must be a node id, got {node_text!r}")
        ids = np.asarray(data.node_ids)
        hits = np.flatnonzero(ids == int(node_text))
        if len(hits) == 0:
            raise UnknownItemError(
                f"the body has no node with id {id_text(node_text)}; ids {ids.min()} .. "
                f"{ids.max()}",
                item=id_text(node_text),
            )
        index = int(hits[0])
    else:
        index = int(np.argmax(magnitude.max(axis=0))) if magnitude.size else 0
    values = np.column_stack([u[:, index, :], magnitude.max(axis=1)])
    return values, [*_AXES, "largest"]


def _stress(result: Any, body: object) -> tuple[Array, list[str]]:
    """Largest von Mises stress (solids), or largest |N| and |M| (beams), per record."""
    data = deformable(result, body)[2]
    n = len(result.time)
    if any(kind != "beam2" for kind in data.elements):
        return result.von_mises(body).reshape(n, -1).max(axis=1)[:, None], ["von-mises"]
    sections = result.section_forces(body)  # (n, beams, 2, 6)
    axial = np.abs(sections[..., 0]).reshape(n, -1).max(axis=1)
    bending = np.hypot(sections[..., 4], sections[..., 5]).reshape(n, -1).max(axis=1)
    return np.column_stack([axial, bending]), ["axial", "bending"]


def body_entry(layout: dict[str, Any], body: object) -> tuple[int, dict[str, Any]]:
    """Index and layout entry of a body given by name, index or id; UnknownItemError
    otherwise."""
    entries = layout["bodies"]
    names = [e["name"] for e in entries]
    if isinstance(body, str):
        if body not in names:
            raise UnknownItemError(f"no body named {body!r}; known: {names}", item=body)
        return names.index(body), entries[names.index(body)]
    index = int(getattr(body, "index", body))  # type: ignore[call-overload]
    if not 0 <= index < len(entries):
        raise UnknownItemError(f"body {index} does not exist", item=str(body))
    return index, entries[index]


def deformable(result: Any, body: object) -> tuple[int, str, Any]:
    """Index, name and FlexibleBodyData of a deformable body given by name, index or id;
    UnknownItemError for other bodies."""
    index, entry = body_entry(result.layout, body)
    if entry["kind"] != "flexible" or index not in result.flexible:
        known = [e["name"] for k, e in enumerate(result.layout["bodies"]) if k in result.flexible]
        raise UnknownItemError(
            f"body {entry['name']!r} is not a deformable body; deformable bodies: {known}",
            item=entry["name"],
        )
    return index, entry["name"], result.flexible[index]


def parse_output(spec: str) -> tuple[str, str, str | None]:
    """(reduction, quantity, component) of an output specification; InvalidParameterError
    naming what is wrong."""
    match = _SPEC.match(spec)
    if match is None:
        raise InvalidParameterError(
            f"output {spec!r}: expected REDUCTION(QUANTITY[COMPONENT]), e.g. "
            "'max-abs(deflection:rod:5[y])'",
            item=spec,
        )
    reduction = match["reduction"] or "series"
    if reduction not in REDUCTIONS:
        raise InvalidParameterError(
            f"output {spec!r}: unknown reduction {reduction!r}; known: {', '.join(REDUCTIONS)}",
            item=spec,
        )
    quantity = match["quantity"].strip()
    kind = quantity.partition(":")[0]
    if kind not in PLAIN_QUANTITIES and kind not in ITEM_QUANTITIES:
        known = ", ".join([*PLAIN_QUANTITIES, *ITEM_QUANTITIES])
        raise InvalidParameterError(
            f"output {spec!r}: unknown quantity {kind!r}; known: {known}", item=spec
        )
    return reduction, quantity, match["component"]


def output_unit(spec: str) -> str:
    """The SI unit of the values of an output specification ("" for none, and for a sensor's,
    which its model knows)."""
    _, quantity, component = parse_output(spec)
    kind = quantity.partition(":")[0]
    if kind == "sensor":
        return ""
    label = None if component is None else component.strip()
    if label in MAGNITUDES:
        label = MAGNITUDES[label][0]
    if label is None and kind == "stress":
        label = "von-mises"  # the one component of a body that is not all beams
    return unit_of(kind, label)


def output_value(result: Any, spec: str) -> float | Array:
    """The value of an output specification for `result`: a number, or the time history
    for ``series``. A result without records (a run that failed or was killed before its
    first) has no value: `InvalidParameterError`."""
    reduction, quantity, component = parse_output(spec)
    if not len(result.time):
        raise InvalidParameterError(f"output {spec!r}: the result has no records", item=spec)
    values, labels = quantity_values(result, quantity)
    components = labels + [key for key, of in MAGNITUDES.items() if set(of) <= set(labels)]
    if component is not None:
        key = component.strip()
        if key in MAGNITUDES and set(MAGNITUDES[key]) <= set(labels):
            columns = [labels.index(label) for label in MAGNITUDES[key]]
            values = np.linalg.norm(values[:, columns], axis=1)
        elif key in labels:
            values = values[:, labels.index(key)]
        elif re.fullmatch(r"\d+", key) and int(key) < len(labels):
            values = values[:, int(key)]
        else:
            raise InvalidParameterError(
                f"output {spec!r}: no component {key!r}; components: {components}", item=spec
            )
    elif values.shape[1] == 1:
        values = values[:, 0]
    else:
        raise InvalidParameterError(
            f"output {spec!r}: {quantity} has components {components}; choose one with [...]",
            item=spec,
        )
    values = np.asarray(values, dtype=float)
    if reduction == "series":
        return values
    if values.size == 0:
        return float("nan")
    reduce = {
        "max": np.max,
        "min": np.min,
        "max-abs": lambda v: np.max(np.abs(v)),
        "mean": np.mean,
        "rms": lambda v: np.sqrt(np.mean(v**2)),
        "initial": lambda v: v[0],
        "final": lambda v: v[-1],
    }[reduction]
    return float(reduce(values))


# Joint coordinates and the drivers' work -------------------------------------------------------
#: Joint types whose coordinates :func:`joint_coordinates` measures: type -> kinds.
JOINT_COORDINATES = {
    "revolute": ("angle",),
    "cylindrical": ("angle", "slide"),
    "prismatic": ("slide",),
    "inline": ("slide",),
    "planar": ("angle",),
    "angle driver": ("angle",),
    "translation driver": ("slide",),
}


def marker_motion(result: Any, marker: int) -> tuple[Array, Array, Array, Array]:
    """Position (m), orientation, velocity (m/s) and angular velocity (rad/s) of marker
    `marker` (index into the layout's markers) in global axes, per record. A marker on a
    deformable body moves with the elastic displacement of the node it sits on (if it sits
    on one); its orientation is the body frame's (the small elastic rotation is left out),
    and so is its velocity's elastic part."""
    entry = result.layout["markers"][marker]
    body = int(entry["body"])
    kind = result.layout["bodies"][body]["kind"]
    n = len(result.time)
    local = np.asarray(entry["position"], dtype=float)
    frame = np.asarray(entry["orientation"], dtype=float)
    if kind == "ground":
        zeros = np.zeros((n, 3))
        return np.tile(local, (n, 1)), np.tile(frame, (n, 1, 1)), zeros, zeros.copy()
    if kind in ("rigid", "flexible"):
        rotation = np.asarray(result.orientation(body))
    else:
        rotation = np.tile(np.eye(3), (n, 1, 1))
    offset = np.tile(local, (n, 1))
    data = result.flexible.get(body) if kind == "flexible" else None
    if data is not None:
        nodes = np.asarray(data.nodes, dtype=float)
        distance = np.linalg.norm(nodes - local, axis=1)
        size = max(float(np.ptp(nodes, axis=0).max()), 1e-300)
        nearest = int(np.argmin(distance))
        if distance[nearest] <= 1e-9 * size:
            offset = offset + np.asarray(result.node_displacements(body))[:, nearest, :]
    arm = np.einsum("nij,nj->ni", rotation, offset)
    omega = np.asarray(result.angular_velocity(body))
    position = np.asarray(result.position(body)) + arm
    velocity = np.asarray(result.velocity(body)) + np.cross(omega, arm)
    return position, rotation @ frame, velocity, omega


def joint_coordinates(result: Any) -> list[tuple[str, str, Array, Array]]:
    """(joint, "angle" or "slide", values, rates) of every joint that has a coordinate (see
    :data:`JOINT_COORDINATES`): the angle (rad) of marker 2's x axis from marker 1's about
    marker 1's z axis, continued over turns, or the slide (m) of marker 2's origin along
    marker 1's z axis, and their rates (rad/s, m/s), per record. Drivers on the markers of
    another listed joint are left out (that joint's coordinate is the driven one)."""
    joints = [j for j in result.layout["joints"] if j["type"] in JOINT_COORDINATES]
    free = {frozenset(j["markers"]) for j in joints if "driver" not in j["type"]}
    out: list[tuple[str, str, Array, Array]] = []
    for joint in joints:
        if "driver" in joint["type"] and frozenset(joint["markers"]) in free:
            continue
        first, second = (marker_motion(result, int(m)) for m in joint["markers"])
        p1, a1, v1, w1 = first
        p2, a2, v2, w2 = second
        axis = a1[:, :, 2]
        for kind in JOINT_COORDINATES[joint["type"]]:
            if kind == "angle":
                sine = np.einsum("ni,ni->n", a1[:, :, 1], a2[:, :, 0])
                cosine = np.einsum("ni,ni->n", a1[:, :, 0], a2[:, :, 0])
                values = np.unwrap(np.arctan2(sine, cosine))
                rates = np.einsum("ni,ni->n", w2 - w1, axis)
            else:
                d = p2 - p1
                values = np.einsum("ni,ni->n", axis, d)
                rates = np.einsum("ni,ni->n", np.cross(w1, axis), d) + np.einsum(
                    "ni,ni->n", axis, v2 - v1
                )
            out.append((joint["name"], kind, values, rates))
    return out


def driver_rates(result: Any, driver: str) -> Array:
    """The rate of the coordinate that driver `driver` prescribes (rad/s or m/s) per record,
    from the motion of its markers (:func:`marker_motion`)."""
    joint = next(j for j in result.layout["joints"] if j["name"] == driver)
    first, second = (marker_motion(result, int(m)) for m in joint["markers"])
    axis = first[1][:, :, 2]
    if joint["type"] == "angle driver":
        return np.einsum("ni,ni->n", second[3] - first[3], axis)
    d = second[0] - first[0]
    return np.einsum("ni,ni->n", np.cross(first[3], axis), d) + np.einsum(
        "ni,ni->n", axis, second[2] - first[2]
    )


def driver_power(result: Any) -> Array:
    """The power (W) of all angle and translation drivers per record: effort times the rate
    of the driven coordinate, summed."""
    total = np.zeros(len(result.time))
    for joint in result.layout["joints"]:
        if joint["type"] in ("angle driver", "translation driver"):
            effort = np.asarray(result.driver_effort(joint["name"]))
            total += effort * driver_rates(result, joint["name"])
    return total


def cumulative_integral(time: Array, values: Array) -> Array:
    """The trapezoidal integral of `values` over `time` from the first record to each."""
    total = np.zeros(len(time))
    total[1:] = np.cumsum(0.5 * (values[1:] + values[:-1]) * np.diff(time))
    return total


def force_work(result: Any) -> Array:
    """The work (J) of the forces no potential energy accounts for
    (`Result.nonconservative_power`: loads, actuators, callback forces, dampers and
    structural damping) from the first record to each: the trapezoidal integral of their
    power over the records. NaN for results files written before the power was recorded."""
    return cumulative_integral(np.asarray(result.time), result.nonconservative_power)


def driver_work(result: Any) -> Array:
    """The work (J) done by all angle and translation drivers from the first record to each
    record: the trapezoidal integral of :func:`driver_power` over the records (second order
    in the output interval)."""
    return cumulative_integral(np.asarray(result.time), driver_power(result))
