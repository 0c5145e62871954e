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
...); a quantity of several components needs one.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

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
                f"the body has no node with id {node_text}; ids {ids.min()} .. {ids.max()}",
                item=node_text,
            )
        index = int(hits[0])
    else:
        index = int(np.argmax(magnitude.max(axis=0))) if magnitude.size else 0
    values = np.column_stack([u[:, index, :], magnitude.max(axis=1)])
    return values, [*_AXES, "largest"]


def _stress(result: Any, body: object) -> tuple[Array, list[str]]:
    """Largest von Mises stress (solids), or largest |N| and |M| (beams), per record."""
    from .fe.stress import von_mises

    data = deformable(result, body)[2]
    n = len(result.time)
    if any(kind != "beam2" for kind in data.elements):
        return von_mises(result.stresses(body)).reshape(n, -1).max(axis=1)[:, None], ["von-mises"]
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


def output_value(result: Any, spec: str) -> float | Array:
    """The value of an output specification for `result`: a number, or the time history
    for ``series``."""
    reduction, quantity, component = parse_output(spec)
    values, labels = quantity_values(result, quantity)
    if component is not None:
        key = component.strip()
        if key in labels:
            values = values[:, labels.index(key)]
        elif re.fullmatch(r"\d+", key) and int(key) < len(labels):
            values = values[:, int(key)]
        else:
            raise InvalidParameterError(
                f"output {spec!r}: no component {key!r}; components: {labels}", item=spec
            )
    elif values.shape[1] == 1:
        values = values[:, 0]
    else:
        raise InvalidParameterError(
            f"output {spec!r}: {quantity} has components {labels}; choose one with [...]",
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
