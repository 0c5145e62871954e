"""Analyses of a model at one state: static and steady equilibrium, linearization, and the
eigenvalues of the linearized motion (for example the frequencies of a rotating blade).

    eq = fm.equilibrium(system)            # static, or steady under prescribed motion
    result = fm.simulate(system, 1.0, 1e-3, initial_state=eq)   # no start-up transient
    lin = fm.linearize(system, eq)
    lin.frequencies()                      # Hz, damped natural frequencies

Both work on the augmented equations (seed eqs. 20, 25) through ``Model.evaluate``.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._checks import integer, number, numbers_array, value_text
from .errors import (
    ArgumentTypeError,
    EquilibriumError,
    FreeMotionError,
    InitialConditionsError,
    InvalidModelError,
    InvalidParameterError,
)
from .rotation import angular_velocity, euler_parameter_rates, euler_parameters_to_matrix, skew
from .state import EquilibriumState, State
from .state_space import (
    BodyPosition,
    ElasticCoordinate,
    NodeDisplacement,
    PointLoad,
    StateSpace,
    input_forces,
    output_rows,
)
from .system import identity_of, unheld_frame_error

if TYPE_CHECKING:
    import scipy.sparse as sp

Array = NDArray[np.float64]

_log = logging.getLogger("flexmbd.analysis")


def _model(model: _core.Model | _core.System, name: str = "model") -> _core.Model:
    """`model` compiled (a System) or as it is (a Model); an `ArgumentTypeError` naming the
    parameter `name` for anything else (a loaded model file: its ``.system``)."""
    if isinstance(model, _core.System):
        return model.compile()
    if isinstance(model, _core.Model):
        return model
    raise not_a_model(model, name)


def not_a_model(
    value: Any, name: str, needs: str = "a flexmbd.System or a compiled Model"
) -> ArgumentTypeError:
    """The error of a `value` given as the model `name` that is none: what holds a system (a
    model file's :func:`flexmbd.load_model`, an example) is told to pass its ``.system``."""
    if isinstance(getattr(value, "system", None), _core.System):
        return ArgumentTypeError(
            f"{name} must be {needs}, got a {type(value).__name__}: pass its .system",
            item=name,
        )
    return ArgumentTypeError(
        f"{name} must be {needs}, got {value_text(value)} ({type(value).__name__})", item=name
    )


def _elastic_mask(layout: dict[str, Any]) -> NDArray[np.bool_]:
    """True for the elastic coordinates of deformable bodies."""
    mask = np.zeros(layout["coordinate_count"], dtype=bool)
    for b in layout["bodies"]:
        if b["kind"] == "flexible":
            mask[b["offset"] + 7 : b["offset"] + b["count"]] = True
    return mask


def _matrix(ev: dict[str, Any]) -> sp.csc_matrix:
    import scipy.sparse as sp

    data, indices, indptr, n = ev["matrix"]
    return sp.csc_matrix((data, indices, indptr), shape=(n, n))


def _prescribed_rates(
    model: _core.Model, time: float, q: Array, rigid: NDArray[np.bool_]
) -> tuple[Array, Array]:
    """Velocities and accelerations of the prescribed motion at q (elastic coordinates at
    rest): the solutions of C_q q_dot = -C_t and C_q q_dd = gamma over the non-elastic
    coordinates nearest the steady motion of `_carried_rates`: the bodies that a moving
    driver carries move rigidly with its driven body (a bob on a free hinge of a turning hub
    turns with the hub, where the minimum-norm solution turned it backwards), the others
    nearest rest."""
    nq = model.coordinate_count
    zero_q = np.zeros(nq)
    zero_l = np.zeros(model.constraint_count)
    ev = model.evaluate(time, q, zero_q, zero_q, zero_l, position=1.0)
    cq = _matrix(ev)[nq:, :nq].toarray()[:, rigid]
    qd = np.zeros(nq)
    qdd = np.zeros(nq)
    # A driver moves where it has a rate, or accelerates from rest (its C_tt in gamma at zero
    # velocity: a driver started from rest was taken for a still one, and the equilibrium
    # left out the inertia of its acceleration).
    moving = (ev["constraint_rate"] != 0.0) | (
        model.evaluate(time, q, zero_q, zero_q, zero_l)["gamma"] != 0.0
    )
    if not np.any(moving):
        return qd, qdd
    qd[rigid] = np.linalg.lstsq(cq, -ev["constraint_rate"], rcond=None)[0]
    gamma = model.evaluate(time, q, qd, zero_q, zero_l)["gamma"]
    qdd[rigid] = np.linalg.lstsq(cq, gamma, rcond=None)[0]
    carried = _carried_rates(model.describe(), moving, q, qd, qdd)
    if carried is None:
        return qd, qdd
    target_qd, target_qdd = carried
    qd = target_qd.copy()
    qd[~rigid] = 0.0
    correction = -ev["constraint_rate"] - cq @ qd[rigid]
    qd[rigid] += np.linalg.lstsq(cq, correction, rcond=None)[0]
    gamma = model.evaluate(time, q, qd, zero_q, zero_l)["gamma"]
    qdd = target_qdd.copy()
    qdd[~rigid] = 0.0
    qdd[rigid] += np.linalg.lstsq(cq, gamma - cq @ qdd[rigid], rcond=None)[0]
    return qd, qdd


def _carried_rates(
    layout: dict[str, Any], moving: NDArray[np.bool_], q: Array, qd: Array, qdd: Array
) -> tuple[Array, Array] | None:
    """The rates of the reference coordinates with which the bodies each moving driver (rows
    `moving`: with a rate or an acceleration) carries
    move rigidly with its driven body (None when no body is carried but the driven ones).

    A driver's driven body is that of its second marker (its first when the second is on the
    ground); the bodies it carries are those joined to it by joints other than drivers,
    without passing through the ground or the driver's other body. The driven body's twist
    (velocity, angular velocity and their rates) is read from `qd`, `qdd` (the minimum-norm
    rates, exact for a body the constraints move fully); the twists of nested drivers add.
    """
    bodies, markers, joints = layout["bodies"], layout["markers"], layout["joints"]
    ground = {i for i, b in enumerate(bodies) if b["kind"] == "ground"}
    links: dict[int, set[int]] = {i: set() for i in range(len(bodies))}
    for joint in joints:
        if "driver" not in joint["type"]:
            a, b = (markers[m]["body"] for m in joint["markers"])
            links[a].add(b)
            links[b].add(a)
    twists: dict[int, list[tuple[int, int]]] = {}
    carried_any = False
    for joint in joints:
        rows = slice(joint["row"], joint["row"] + len(joint["equations"]))
        if "driver" not in joint["type"] or not np.any(moving[rows]):
            continue
        other, driven = (markers[m]["body"] for m in joint["markers"])
        if driven in ground:
            other, driven = driven, other
        if driven in ground or driven == other:
            continue
        seen, stack = {driven}, [driven]
        while stack:
            for nxt in links[stack.pop()]:
                if nxt not in seen and nxt not in ground and nxt != other:
                    seen.add(nxt)
                    stack.append(nxt)
        carried_any |= len(seen) > 1
        for body in seen:
            twists.setdefault(body, []).append((driven, joint["row"]))
    if not carried_any:
        return None

    def twist(body: int) -> tuple[Array, Array, Array, Array, Array]:
        """Origin, velocity, angular velocity and their rates of a body's reference frame."""
        o = bodies[body]["offset"]
        r, v, a = q[o : o + 3], qd[o : o + 3], qdd[o : o + 3]
        if bodies[body]["count"] < 7:
            return r, v, a, np.zeros(3), np.zeros(3)
        p, pd, pdd = q[o + 3 : o + 7], qd[o + 3 : o + 7], qdd[o + 3 : o + 7]
        # Global omega = 2 E(p) p_dot; its rate 2 E(p) p_dd (E(p_dot) p_dot = 0).
        return r, v, a, angular_velocity(p, pd), angular_velocity(p, pdd)

    target_qd, target_qdd = qd.copy(), qdd.copy()
    for body, sources in twists.items():
        o, count = bodies[body]["offset"], bodies[body]["count"]
        if count < 3:
            continue
        r = q[o : o + 3]
        v, a, w, alpha = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
        for driven, _ in sources:
            r_d, v_d, a_d, w_d, alpha_d = twist(driven)
            d = r - r_d
            v += v_d + np.cross(w_d, d)
            a += a_d + np.cross(alpha_d, d) + np.cross(w_d, np.cross(w_d, d))
            w += w_d
            alpha += alpha_d
        target_qd[o : o + 3], target_qdd[o : o + 3] = v, a
        if count >= 7:
            p = q[o + 3 : o + 7]
            pd = euler_parameter_rates(p, w)
            target_qd[o + 3 : o + 7] = pd
            target_qdd[o + 3 : o + 7] = euler_parameter_rates(pd, w) + euler_parameter_rates(
                p, alpha
            )
    return target_qd, target_qdd


#: Largest violation of a driver's equations at the start of `equilibrium` (rad or m): beyond
#: it the drivers have moved far from the starting coordinates, where Newton's method
#: diverges or finds another branch (an angle driver is met by the angle plus pi too).
DRIVER_START_LIMIT = 0.1


def _turned_to_drivers(model: _core.Model, time: float, q: Array, layout: dict) -> Array:
    """`q` with the parts each driver moves turned (an angle driver) or shifted (a
    translation driver) rigidly to the driver's value at `time`: a rotor built at its
    driver's start, asked for its steady rotation at t = 20 s (the hub 75 rad on), starts
    from the configuration the driver has turned it to. Only the drivers that `q` meets at
    t = 0 (a turn or shift within :data:`DRIVER_START_LIMIT`): a model built off its
    driver's start (a link at 0.05 rad on a driver at pi) is refused by the checks, as a run
    refuses it. The part is the driven marker's body and every body joined to it, not
    through the ground or the driver's other body; the turn is about the z axis of the
    driver's first marker, by the angle at which the driver's equation C = rho sin(theta -
    f) vanishes (theta - f = atan2(C, dC/dturn), exact for a rigid turn). A turn that would
    break another joint by more than :data:`DRIVER_START_LIMIT` (a driven crank of a
    four-bar) is not made: the coordinates are returned as they were (and the drivers'
    check names the driver)."""
    nq, nc = model.coordinate_count, model.constraint_count
    bodies, markers = layout["bodies"], layout["markers"]
    zero = np.zeros(nq)
    drivers = [j for j in layout["joints"] if j["type"] in ("angle driver", "translation driver")]
    start = np.array(q, dtype=float)
    q = start.copy()
    driver_rows = np.zeros(nc, dtype=bool)
    for joint in drivers:
        driver_rows[joint["row"] : joint["row"] + len(joint["equations"])] = True

    def frame(body: dict[str, Any], q: Array) -> tuple[Array, Array]:
        if body["kind"] == "ground":
            return np.zeros(3), np.eye(3)
        o = body["offset"]
        if body["count"] < 7:
            return q[o : o + 3], np.eye(3)
        return q[o : o + 3], euler_parameters_to_matrix(q[o + 3 : o + 7])

    def needed(
        joint: dict[str, Any], part: list[int], sense: float, at: float, q: Array
    ) -> tuple[float, Array, Array]:
        """The turn (rad) or shift (m) of `part` that meets `joint` at time `at`, the axis
        and a point on it."""
        first = markers[joint["markers"][0]]
        origin, rotation = frame(bodies[first["body"]], q)
        axis = rotation @ np.asarray(first["orientation"], dtype=float)[:, 2]
        centre = origin + rotation @ np.asarray(first["position"], dtype=float)
        ev = model.evaluate(at, q, zero, zero, np.zeros(nc), mass=1.0)
        value = float(ev["residual"][nq + joint["row"]])
        if joint["type"] == "translation driver":
            return -sense * value, axis, centre
        # The rate of C under a unit turn of the part about the axis: rho cos(theta - f).
        turn = np.zeros(nq)
        for b in part:
            o, count = bodies[b]["offset"], bodies[b]["count"]
            turn[o : o + 3] = np.cross(axis, q[o : o + 3] - centre)
            if count >= 7:
                turn[o + 3 : o + 7] = euler_parameter_rates(q[o + 3 : o + 7], axis, "global")
        rate = float(_matrix(ev)[nq + joint["row"], :nq].toarray().ravel() @ turn)
        # C(turn) = A sin(turn + beta), A cos(beta) = rate. Where theta = f, dC/dtheta > 0:
        # the turn is -beta when the part carries the second marker (theta grows with it),
        # pi - beta when it carries the first (theta falls).
        angle = -np.arctan2(value, rate) + (0.0 if sense > 0 else np.pi)
        return float(np.angle(np.exp(1j * angle))), axis, centre  # (in (-pi, pi])

    for joint in drivers:
        first, second = (markers[m] for m in joint["markers"])
        moving, sense = second["body"], 1.0
        if bodies[moving]["kind"] == "ground":
            moving, sense = first["body"], -1.0
        part = _joined_part(layout, moving, exclude=(first["body"], second["body"]), joint=joint)
        if abs(needed(joint, part, sense, 0.0, start)[0]) > DRIVER_START_LIMIT:
            continue  # (the model was not built at its driver's start: the checks say so)
        amount, axis, centre = needed(joint, part, sense, time, q)
        if abs(amount) <= 1e-14:
            continue
        if joint["type"] == "translation driver":
            for b in part:
                o = bodies[b]["offset"]
                q[o : o + 3] += amount * axis
            continue
        spin = np.concatenate([[np.cos(0.5 * amount)], np.sin(0.5 * amount) * axis])
        turned = euler_parameters_to_matrix(spin)
        for b in part:
            o, count = bodies[b]["offset"], bodies[b]["count"]
            q[o : o + 3] = centre + turned @ (q[o : o + 3] - centre)
            if count >= 7:
                q[o + 3 : o + 7] = _quaternion_product(spin, q[o + 3 : o + 7])
    if np.array_equal(q, start):
        return start
    ev = model.evaluate(time, q, zero, zero, np.zeros(nc))
    before = model.evaluate(time, start, zero, zero, np.zeros(nc))["residual"][nq:]
    others = np.abs(ev["residual"][nq:])[~driver_rows]
    if others.size and others.max() > max(DRIVER_START_LIMIT, np.abs(before[~driver_rows]).max()):
        return start  # (the turn broke another joint: a loop the driver does not turn alone)
    moved = float(np.max(np.abs(q - start)))
    _log.info(
        "the parts the drivers move turned to their values at t = %g (by up to %.3g)", time, moved
    )
    return q


def _joined_part(
    layout: dict[str, Any], body: int, exclude: tuple[int, ...], joint: dict[str, Any]
) -> list[int]:
    """`body` and the bodies joined to it by joints other than `joint`, not through the
    ground or the bodies `exclude` (the driver's own two)."""
    bodies, markers = layout["bodies"], layout["markers"]
    links: dict[int, set[int]] = {}
    for other in layout["joints"]:
        if other is joint or other["name"] == joint["name"]:
            continue
        a, b = (markers[m]["body"] for m in other["markers"])
        links.setdefault(a, set()).add(b)
        links.setdefault(b, set()).add(a)
    part, stack = {body}, [body]
    while stack:
        for other in links.get(stack.pop(), ()):
            if other in part or other in exclude or bodies[other]["kind"] == "ground":
                continue
            part.add(other)
            stack.append(other)
    return sorted(part)


def _quaternion_product(a: Array, b: Array) -> Array:
    """The Euler parameters of the rotation A(a) A(b)."""
    return np.concatenate(
        [[a[0] * b[0] - a[1:] @ b[1:]], a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])]
    )


def _check_drivers_at_start(model: _core.Model, time: float, q: Array, layout: dict) -> None:
    """InvalidModelError naming the driver when the starting coordinates are far from where
    the drivers put the model at `time` (a steady rotation asked for at t = 20 s from the
    model's initial coordinates, with the hub 75 rad on); `InitialConditionsError` naming an
    angle driver whose joint starts more than a quarter turn from its angle, as a run
    refuses it: its equation sin(theta - f) = 0 holds at theta = f + pi too, where Newton's
    method stayed (a link held at pi returned at 0, its torque of the other sign)."""
    nq, nc = model.coordinate_count, model.constraint_count
    zero_q = np.zeros(nq)
    ev = model.evaluate(time, q, zero_q, zero_q, np.zeros(nc), mass=1.0)
    violation = ev["residual"][nq:]
    jacobian = _matrix(ev)[nq:, :nq].tocsr()
    for joint in layout["joints"]:
        if "driver" not in joint["type"]:
            continue
        rows = slice(joint["row"], joint["row"] + len(joint["equations"]))
        worst = float(np.max(np.abs(violation[rows]), initial=0.0))
        if worst > DRIVER_START_LIMIT:
            raise InvalidModelError(
                f"equilibrium at t = {time:g}: the starting coordinates violate driver "
                f"'{joint['name']}' by {worst:.3g} (its motion has moved on since the initial "
                "configuration); pass coordinates= of a configuration at that time, for "
                "example result.state(k).coordinates of a run, or the initial coordinates "
                "turned to the drivers' angles",
                item=f"driver '{joint['name']}'",
            )
    for joint in layout["joints"]:
        if joint["type"] != "angle driver":
            continue
        cosine = _driver_cosine(layout, q, jacobian[joint["row"]].toarray().ravel(), joint)
        if cosine is not None and cosine < 0.0:
            off = float(np.arctan2(abs(violation[joint["row"]]), cosine))
            raise InitialConditionsError(
                f"equilibrium at t = {time:g}: angle driver '{joint['name']}' (its joint starts "
                f"{off:.4f} rad from the prescribed angle: the driver's equation "
                "sin(theta - f) = 0 holds half a turn from f too, and the equilibrium would "
                "hold the joint on that branch, its torque of the opposite sign); start the "
                "joint within a quarter turn of the prescribed angle (its initial orientation, "
                "or coordinates=)",
                item=f"driver '{joint['name']}'",
                time=time,
            )


def _driver_cosine(
    layout: dict[str, Any], q: Array, row: Array, joint: dict[str, Any]
) -> float | None:
    """cos(theta - f) of angle driver `joint` at `q`, up to a positive factor: the rate of
    its equation (`row`: its row of C_q) under a turn of its second marker's body about its
    first marker's z axis (or of the first body the other way, when the second does not
    turn); None when neither body turns (a point mass). A node marker's axis is taken from
    its body's frame, which its elastic rotation moves a little: the sign is kept."""
    bodies, markers = layout["bodies"], layout["markers"]
    first, second = (markers[m] for m in joint["markers"])

    def frame(body: dict[str, Any]) -> Array | None:
        if body["kind"] == "ground":
            return np.eye(3)
        if body["count"] < 7:
            return None
        return euler_parameters_to_matrix(q[body["offset"] + 3 : body["offset"] + 7])

    rotation = frame(bodies[first["body"]])
    if rotation is None:
        return None
    axis = rotation @ np.asarray(first["orientation"], dtype=float)[:, 2]
    for marker, sense in ((second, 1.0), (first, -1.0)):
        body = bodies[marker["body"]]
        if body["kind"] != "ground" and body["count"] >= 7:
            turn = np.zeros(len(q))
            parameters = slice(body["offset"] + 3, body["offset"] + 7)
            turn[parameters] = euler_parameter_rates(q[parameters], axis, "global")
            return sense * float(row @ turn)
    return None


#: Nodal deformable bodies with at least this many elastic coordinates are eliminated from
#: the Newton solves of `equilibrium` through a sparse Cholesky factor of their elastic
#: block (nested dissection of their mesh): a general sparse LU of the whole matrix of a
#: 108,836-node solid ran out of memory, 17 GB after 7 minutes.
ELIMINATE_ABOVE = 2000


def _newton_solve(
    a: sp.csc_matrix,
    rhs: Array,
    layout: dict[str, Any],
    flexible: dict[int, Any],
    kept_factors: dict[int, tuple[sp.csr_matrix, Any]],
) -> Array:
    """The solution of a x = rhs for a Newton matrix of the augmented equations. The elastic
    blocks of large nodal bodies (symmetric positive definite: the stiffness, at rest) are
    factorized by the sparse Cholesky of the preprocessor and eliminated (Schur complement
    on the other unknowns: the reference coordinates of all bodies, the elastic coordinates
    of small ones and the multipliers, solved densely); everything else, and any block that
    is not symmetric positive definite, by a sparse LU of the whole matrix. `kept_factors`
    (body index -> block, factor) keeps the factors between the iterations: a block equal to
    the kept one (the stiffness at rest is) is not factorized again."""
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla

    from .fe.modal import factorize

    blocks = []
    for index, body in enumerate(layout["bodies"]):
        data = flexible.get(index)
        if body["kind"] != "flexible" or data is None or data.modes is not None:
            continue
        if body["count"] - 7 >= ELIMINATE_ABOVE:
            columns = np.arange(body["offset"] + 7, body["offset"] + body["count"])
            blocks.append((index, columns, data))
    rows = a.tocsr()
    factors = []
    for index, columns, data in blocks:
        block = rows[columns][:, columns]
        kept = kept_factors.get(index)
        if kept is not None and kept[0].shape == block.shape and (kept[0] != block).nnz == 0:
            factors.append(kept[1])
            continue
        scale = float(abs(block).max())
        if not scale > 0 or abs(block - block.T).max() > 1e-12 * scale:
            factors = []
            break
        try:
            factor = factorize(
                block.tocsc(),
                dofs=np.asarray(data.reference.free_dofs, dtype=np.int64),
                nodes=data.nodes,
                dofs_per_node=data.dofs_per_node,
                name="elastic block of the equilibrium",
            )
        except (InvalidModelError, ValueError):
            factors = []
            break
        kept_factors[index] = (block, factor)
        factors.append(factor)
    if not factors:
        try:
            with warnings.catch_warnings():
                # An exactly singular matrix gives NaN, which the caller reports.
                warnings.simplefilter("ignore", spla.MatrixRankWarning)
                return spla.spsolve(a.tocsc(), rhs)
        except RuntimeError as exc:  # pragma: no cover - scipy raises on exact singularity
            raise InvalidModelError(f"equilibrium: singular matrix ({exc})") from exc
    eliminated = np.concatenate([columns for _, columns, _ in blocks])
    kept = np.setdiff1d(np.arange(a.shape[0]), eliminated)
    coupling = rows[eliminated][:, kept].tocsc()
    used = np.flatnonzero(np.diff(coupling.indptr))  # kept unknowns coupled to the blocks
    # Z = A_ee^-1 [A_ek (used columns), b_e], block by block.
    right = np.hstack([coupling[:, used].toarray(), rhs[eliminated, None]])
    solved = np.empty_like(right)
    start = 0
    for (_, columns, _), factor in zip(blocks, factors, strict=True):
        part = slice(start, start + len(columns))
        solved[part] = factor.solve(np.ascontiguousarray(right[part]))
        start += len(columns)
    back = rows[kept][:, eliminated]
    schur = rows[kept][:, kept].toarray()
    schur[:, used] -= back @ solved[:, :-1]
    reduced = rhs[kept] - back @ solved[:, -1]
    try:
        x_kept = sla.solve(schur, reduced)
    except (sla.LinAlgError, ValueError):
        x_kept = np.full(len(kept), np.nan)
    x = np.empty(a.shape[0])
    x[kept] = x_kept
    x[eliminated] = solved[:, -1] - solved[:, :-1] @ x_kept[used]
    return x


def _static_multipliers(
    model: _core.Model, time: float, q: Array, rigid: NDArray[np.bool_]
) -> Array:
    """The multipliers that balance the applied forces at q best (least squares of
    C_q^T lambda = -residual at lambda = 0): Newton's first matrix then holds the stiffness of
    the constraint forces (a pendulum started near upright sees its link compressed)."""
    nq, nc = model.coordinate_count, model.constraint_count
    if nc == 0:
        return np.zeros(0)
    qd, qdd = _prescribed_rates(model, time, q, rigid)
    ev = model.evaluate(time, q, qd, qdd, np.zeros(nc), position=1.0)
    jacobian = _matrix(ev)[nq:, :nq].toarray()
    lam = np.linalg.lstsq(jacobian.T, -ev["residual"][:nq], rcond=None)[0]
    return lam if np.all(np.isfinite(lam)) else np.zeros(nc)


def _violated_rows(values: Array, kept: NDArray[np.int64], floor: float) -> NDArray[np.int64]:
    """The constraint rows not in `kept` whose |C| is above `floor`."""
    removed = np.setdiff1d(np.arange(len(values)), kept)
    return removed[np.abs(values[removed]) > floor]


def _row_names(layout: dict[str, Any], rows: NDArray[np.int64]) -> tuple[list[str], str]:
    """The names of the joints of constraint `rows`, and "joint 'hinge' equation 'x', ..."
    for them (rows of no joint by number)."""
    joints, names = [], []
    for row in rows:
        for joint in layout["joints"]:
            if joint["row"] <= row < joint["row"] + len(joint["equations"]):
                equation = joint["equations"][row - joint["row"]]
                names.append(f"joint '{joint['name']}' equation '{equation}'")
                joints.append(joint["name"])
                break
        else:
            names.append(f"constraint row {row}")
    return joints, ", ".join(names)


def _kept(a: sp.csc_matrix, unknowns: NDArray[np.int64]) -> sp.csc_matrix:
    """The rows and columns `unknowns` of `a` (`a` itself when they are all)."""
    return a if len(unknowns) == a.shape[0] else a[unknowns][:, unknowns].tocsc()


def _moved_multipliers(a: sp.csc_matrix, nq: int, lam: Array, rows: NDArray[np.int64]) -> Array:
    """Multipliers of the constraint `rows` alone (the others 0) with the same constraint
    force C_q^T lambda as `lam` (least squares), for C_q the rows below `nq` of `a`."""
    jacobian = a[nq:, :nq].toarray()
    moved = np.zeros_like(lam)
    moved[rows] = np.linalg.lstsq(jacobian[rows].T, jacobian.T @ lam, rcond=None)[0]
    return moved


#: Residual (N, N m) below which a state is in balance as it is: the equilibrium iteration
#: takes no step there.
BALANCED = 1e-12


#: Relative tolerance of the rank of C_q in the choice of redundant rows (the runs' default,
#: DEFAULT_RANK_TOLERANCE of the core's partitioning).
RANK_TOLERANCE = 1e-9


#: The rows kept in Newton's matrix of an equilibrium with redundant constraints are chosen
#: again when their conditioning (smallest pivot of their QR over the largest) falls below
#: this fraction of the best choice's.
REPIVOT_RATIO = 0.1


def _independent_rows(a: sp.csc_matrix, nq: int, current: NDArray[np.int64]) -> NDArray[np.int64]:
    """The rows of C_q (the rows below `nq` of the Newton matrix `a`) that Newton's matrix
    keeps: the `current` ones while they stay independent, otherwise those a QR factorization
    of C_q^T with column pivoting keeps, in order. Independent: the pivots of the QR of the
    rows (each scaled to unit length, so that a far iterate's scales do not decide) above
    RANK_TOLERANCE times the largest. The equations of redundant joints (a spatial four-bar
    of revolute joints, Bricard's mechanism) are left out of Newton's matrix, which they would
    make singular, as the runs' `redundant_constraints="remove"` does, and chosen again when
    the kept ones become dependent as the mechanism moves."""
    import scipy.linalg as sla

    jacobian = a[nq:, :nq].tocsc()
    nc = jacobian.shape[0]
    used = np.flatnonzero(np.diff(jacobian.indptr))
    dense = jacobian[:, used].toarray()
    lengths = np.linalg.norm(dense, axis=1)
    if nc == 0 or not np.all(np.isfinite(dense)):
        return current
    # Rows that are identically zero (the rotation equations of a prismatic joint on a point
    # mass, which has no rotation) are dependent on any others: they were kept, and Newton's
    # matrix was singular ("3 directions without stiffness") though the runs remove them.
    nonzero = np.flatnonzero(lengths > 0.0)
    dense[nonzero] /= lengths[nonzero, None]

    def pivoted(rows: NDArray[np.int64]) -> tuple[NDArray[np.int64], float]:
        """The independent ones of `rows`, and their smallest pivot over the largest."""
        rows = rows[lengths[rows] > 0.0]
        if not len(rows):
            return rows, 0.0
        r, pivots = sla.qr(dense[rows].T, mode="r", pivoting=True)
        diagonal = np.abs(np.diag(r))
        if not diagonal.size or diagonal[0] == 0.0:
            return rows[:0], 0.0
        rank = int(np.sum(diagonal > RANK_TOLERANCE * diagonal[0]))
        return rows[pivots[:rank]], float(diagonal[rank - 1] / diagonal[0])

    best, best_ratio = pivoted(nonzero)
    if len(current) == len(best) and np.all(lengths[current] > 0.0):
        kept, ratio = pivoted(current)
        if len(kept) == len(current) and ratio >= REPIVOT_RATIO * best_ratio:
            return current
    return np.sort(best).astype(np.int64)


#: Largest change of a body's Euler parameters in one iteration of the search for a stable
#: equilibrium (about 0.2 rad of rotation).
SEEK_TURN_LIMIT = 0.1

#: Most times the shift of the search for a stable equilibrium is raised (by 4 each time,
#: from 1e-6 of the largest diagonal entry to 67 times it). A direction no such shift makes
#: positive is not a lack of stiffness but a near singular configuration of the constraints
#: (Bricard's mechanism passes one on its way down): a larger shift would only stop the
#: iteration there.
SHIFT_STEPS = 13

#: Eigenvalues of the condensed Newton matrix within this fraction of the largest count as
#: zero (neutral directions, redundant constraints) in the stability test.
NEUTRAL = 1e-9

#: Eigenvalues of the first-order form of modulus (or real part) at most this fraction of
#: the largest |s| (at least 1) are round-off: zero (free motions), not growing. The round-off
#: measured is 2e-17 to 3e-16 of the largest |s| (undamped rotors, Beck's column), so this
#: is about 450 eps. It was 1e-9: the overdamped modes of a nearly massless damped shaft
#: (R8's, |s| = 2.1e11) then set a floor of 212 1/s: the damped rotor's growing whirl
#: (Re s = 1.1) counted as neutral, its 130 rad/s whirl as a free motion, and its 10.4 and
#: 20.7 Hz modes were left out of its frequencies.
EIGEN_ROUND_OFF = 1e-13


def _euler_parameter_mask(layout: dict[str, Any]) -> NDArray[np.bool_]:
    """True for the Euler parameters of the body frames."""
    mask = np.zeros(layout["coordinate_count"], dtype=bool)
    for b in layout["bodies"]:
        if b["kind"] != "ground" and b["count"] >= 7:
            mask[b["offset"] + 3 : b["offset"] + 7] = True
    return mask


def _inertia(
    a: sp.csc_matrix, nq: int, layout: dict[str, Any], factors: dict[int, Any] | None = None
) -> tuple[int, int] | None:
    """The numbers of negative and of zero eigenvalues of Z^T K Z (Z a basis of the null space
    of C_q; K taken symmetric) for the Newton matrix a = [[K, C_q^T], [C_q, 0]], from the
    inertia of a (Sylvester): n_-(a) = n_-(Z^T K Z) + rank C_q, n_0(a) = n_0(Z^T K Z) +
    (rows of C_q - rank C_q). None when it is not known (see `_condensation`). `factors`:
    the kept factors of `_newton_solve`."""
    condensation = _condensation(a, nq, layout, factors)
    return None if condensation is None else condensation.inertia()


@dataclass
class _Condensation:
    """The Newton matrix with its elastic coordinates eliminated: the dense `condensed`
    matrix of the other unknowns (reference coordinates, multipliers; indices `other`), the
    negative and zero pivots of the eliminated block, and the rows and rank of C_q."""

    condensed: Array
    other: NDArray[np.int64]
    negative: int
    zero: int
    rows: int
    rank: int
    _scale: float | None = None

    def scale(self) -> float:
        """The largest |eigenvalue| of the condensed matrix (computed once)."""
        import scipy.linalg as sla

        if self._scale is None:
            values = sla.eigvalsh(self.condensed)
            self._scale = float(np.max(np.abs(values), initial=0.0))
        return self._scale

    def inertia(self, shift: Array | None = None) -> tuple[int, int]:
        """(negative, zero) eigenvalues of Z^T K Z, with `shift` (over all unknowns) added to
        the diagonal of K first; a shift of the reference coordinates leaves the eliminated
        block, and so the condensation, as it is."""
        import scipy.linalg as sla

        condensed = self.condensed
        # The floor of the zero eigenvalues is that of the unshifted matrix: a shift s of the
        # constrained directions makes eigenvalues of about -sigma^2 / s (sigma those of
        # C_q), which a floor relative to the shifted matrix's largest (about s) would count
        # as zero, and the search for a stable equilibrium would raise its shift forever
        # (Bricard's mechanism: shifts of 1e20 and more, and a singular matrix).
        floor = NEUTRAL * self.scale()
        if shift is not None:
            condensed = condensed + np.diag(shift[self.other])
        values = sla.eigvalsh(condensed)
        negative = self.negative + int(np.sum(values < -floor))
        zero = self.zero + int(np.sum(np.abs(values) <= floor))
        return max(negative - self.rank, 0), max(zero - (self.rows - self.rank), 0)


def _condensation(
    a: sp.csc_matrix, nq: int, layout: dict[str, Any], factors: dict[int, Any] | None = None
) -> _Condensation | None:
    """The elastic coordinates of the Newton matrix `a` eliminated by a sparse LDL^T (LU with
    symmetric pivoting, whose pivots carry the inertia of their block), or through the kept
    Cholesky factors of large bodies; None when the pivots are not symmetric or the block is
    exactly singular (the inertia is then not known)."""
    import scipy.sparse.linalg as spla

    sym = ((a + a.T) * 0.5).tocsr()
    mask = _elastic_mask(layout)
    other = np.flatnonzero(np.concatenate([~mask, np.ones(a.shape[0] - nq, dtype=bool)]))
    condensed = sym[other][:, other].toarray()
    negative = zero = 0
    # Large nodal bodies whose (symmetric positive definite) elastic block has a Cholesky
    # factor from the Newton solves: positive pivots, eliminated through that factor.
    rows = a.tocsr()
    for index, (block, factor) in (factors or {}).items():
        body = layout["bodies"][index]
        columns = np.arange(body["offset"] + 7, body["offset"] + body["count"])
        if block.shape != (len(columns),) * 2 or (rows[columns][:, columns] != block).nnz:
            continue
        coupling = sym[columns][:, other].toarray()
        condensed -= coupling.T @ factor.solve(np.ascontiguousarray(coupling))
        mask[columns] = False
    elastic = np.flatnonzero(mask)
    if len(elastic):
        block = sym[elastic][:, elastic].tocsc()
        try:
            lu = spla.splu(
                block,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError:  # an exactly singular elastic block
            return None
        if not np.array_equal(lu.perm_r, lu.perm_c):
            return None
        pivots = lu.U.diagonal()
        floor = NEUTRAL * float(np.max(np.abs(pivots)))
        negative += int(np.sum(pivots < -floor))
        zero += int(np.sum(np.abs(pivots) <= floor))
        coupling = sym[elastic][:, other].toarray()
        condensed -= coupling.T @ lu.solve(coupling)
    jacobian = a[nq:, :nq].toarray()
    rank = int(np.linalg.matrix_rank(jacobian)) if jacobian.size else 0
    return _Condensation(condensed, other, negative, zero, jacobian.shape[0], rank)


def _free_motions(
    a: sp.csc_matrix,
    q: Array,
    nq: int,
    layout: dict[str, Any],
    factors: dict[int, Any] | None = None,
) -> tuple[str, str | None, int]:
    """What makes the Newton matrix `a` = [[K, C_q^T], [C_q, 0]] at coordinates `q` singular,
    for the error of :func:`equilibrium`, the item to name and the number of free directions
    (0 when it is no free motion of the bodies): the null space of its condensation (elastic
    coordinates eliminated, see `_condensation`) read as the motions of the bodies it moves
    (translations, and rotations from the Euler parameters' rates, omega = 2 E(p) p_dot, in
    global axes); the item is the first of those bodies."""
    condensation = _condensation(a, nq, layout, factors)
    if condensation is None:
        return (
            "an elastic block is singular (a deformable body whose reference conditions "
            "leave it a rigid motion?)",
            None,
            0,
        )
    values, vectors = np.linalg.eigh(condensation.condensed)
    zero = np.abs(values) <= NEUTRAL * np.max(np.abs(values), initial=0.0)
    null = np.zeros((a.shape[0], int(np.sum(zero))))
    null[condensation.other] = vectors[:, zero]
    motions, names = [], []
    for body in layout["bodies"] if null.size else []:
        if body["kind"] == "ground" or body["count"] == 0:
            continue
        at = body["offset"]
        part = null[at : at + body["count"]]
        if np.max(np.abs(part), initial=0.0) < 0.1 * np.max(np.abs(null[:nq]), initial=0.0):
            continue
        kinds = []
        translation = part[:3]
        rank = np.linalg.matrix_rank(
            translation, tol=0.1 * np.max(np.abs(translation), initial=1.0)
        )
        if np.max(np.abs(translation)) > 0.1 * np.max(np.abs(part)):
            kinds.append(_directions("translation", translation, rank))
        if body["count"] >= 7:
            rotation = angular_velocity(q[at + 3 : at + 7], part[3:7].T).T
            if np.max(np.abs(rotation)) > 0.1 * np.max(np.abs(part)):
                rank = np.linalg.matrix_rank(rotation, tol=0.1 * np.max(np.abs(rotation)))
                kinds.append(_directions("rotation", rotation, rank))
        if body["kind"] == "flexible" and np.max(np.abs(part[7:]), initial=0.0) > 0.1 * np.max(
            np.abs(part)
        ):
            kinds.append("deformation")
        motions.append(f"body '{body['name']}' ({', '.join(kinds) or 'motion'})")
        names.append(body["name"])
    if motions:
        count = null.shape[1]
        what = "; ".join(motions)
        return (
            f"{count} direction{'s' if count > 1 else ''} without stiffness or constraint, "
            f"moving {what}: hold it by a joint, a spring or a driver, or simulate from the "
            "model's initial state (its free-free modes: fm.linearize_at_rest)",
            names[0],
            count,
        )
    return "a free motion without stiffness", None, 0


def _directions(kind: str, vectors: Array, rank: int) -> str:
    """'translation along (x, y, z)' for one direction of the 3 x k `vectors`, 'translation in
    the plane normal to (...)' for two, 'translation in any direction' for three."""
    u = np.linalg.svd(vectors)[0]
    if rank >= 3:
        return f"{kind} in any direction" if kind == "translation" else f"{kind} about any axis"
    axis = u[:, 0] if rank == 1 else u[:, 2]
    axis = axis * np.sign(axis[np.argmax(np.abs(axis))])
    text = "(" + ", ".join(f"{v:.3g}" for v in axis + 0.0) + ")"
    if rank == 1:
        return f"{kind} along {text}" if kind == "translation" else f"{kind} about {text}"
    return (
        f"{kind} normal to {text}"
        if kind == "translation"
        else f"{kind} about axes normal to {text}"
    )


def _shifted_to_stable(
    a: sp.csc_matrix,
    nq: int,
    layout: dict[str, Any],
    rigid: NDArray[np.bool_],
    factors: dict[int, Any],
) -> sp.csc_matrix:
    """The Newton matrix with the smallest shift s (a power of 4 times 1e-6 of its largest
    reference-coordinate diagonal entry, at least 1e-6) added to the diagonal of the
    reference coordinates that makes it positive definite in every free direction; a
    unchanged when it is. The elastic coordinates are eliminated once: the shift does not
    touch them."""
    import scipy.sparse as sp

    condensation = _condensation(a, nq, layout, factors)
    if condensation is not None and condensation.inertia() == (0, 0):
        return a
    shift_rows = np.zeros(a.shape[0])
    shift_rows[:nq][rigid] = 1.0
    diagonal = np.abs(a.diagonal()[:nq][rigid])
    shift = 1e-6 * max(float(np.max(diagonal, initial=0.0)), 1.0)
    for _ in range(SHIFT_STEPS):
        if condensation is not None and condensation.inertia(shift * shift_rows) == (0, 0):
            break
        shift *= 4.0
    return (a + sp.diags(shift * shift_rows)).tocsc()


def _symmetric(matrix: Any) -> bool:
    """Whether `matrix` (sparse or dense) is symmetric: every |K_ij - K_ji| within
    :data:`NEUTRAL` of sqrt(r_i r_j), r_i the largest entry of row i (a follower load's
    stiffness is not: 6e-6 for Beck's column at 5 EI / L^2). Row by row, not against the
    largest entry of all: a stiff body elsewhere in the model (a steel beam's 2.6e9) hid the
    asymmetry of Ziegler's follower-loaded pendulum (0.1), whose flutter was then reported
    as divergence."""
    import scipy.sparse as sp

    if matrix.shape[0] == 0:
        return True
    if sp.issparse(matrix):
        rows = np.asarray(abs(matrix).max(axis=1).todense()).ravel()
        difference = sp.coo_matrix(matrix - matrix.T)
        i, j, values = difference.row, difference.col, np.abs(difference.data)
    else:
        dense = np.asarray(matrix, dtype=float)
        rows = np.abs(dense).max(axis=1)
        i, j = np.nonzero(dense - dense.T)
        values = np.abs(dense - dense.T)[i, j]
    return bool(np.all(values <= NEUTRAL * np.sqrt(rows[i] * rows[j])))


#: Largest number of independent coordinates whose eigenvalues (dense, of the first-order
#: form: 2n x 2n) decide the stability of an equilibrium with a nonsymmetric stiffness;
#: above it the stability is not determined (None).
EIGENVALUE_STABILITY_LIMIT = 1000


#: The stability fields of an :class:`EquilibriumState` whose stability is not determined.
UNDECIDED: dict[str, Any] = {"stable": None, "unstable_directions": 0, "neutral_directions": 0}


def _linearized_stability(model: _core.Model, state: EquilibriumState) -> dict[str, Any]:
    """The stability fields of :class:`EquilibriumState` from the linearization about
    `state` (its stiffness holds the spin softening of the turning frames, B^T (K B +
    D B_dot + M B_dd)): for a symmetric stiffness its inertia, as at rest (negative
    eigenvalues: unstable directions; zero: neutral); for a nonsymmetric one (follower
    loads) the eigenvalues of the linearized motion, which the inertia does not decide
    (Beck's column has none negative and flutters above 20.05 EI / L^2, and its symmetric
    part has negative ones below): unstable where some grow (Re s above :data:`EIGEN_ROUND_OFF`
    of the largest |s|, at least 1; each real one and each complex pair a direction),
    stable otherwise, not determined above :data:`EIGENVALUE_STABILITY_LIMIT`
    coordinates. The eigenvalues also decide a symmetric stiffness with negative directions
    where the velocity terms hold gyroscopic (skew-symmetric) parts, which can hold them: a
    rotor above its critical speed has negative stiffness in its turning frame and whirls
    stably, undamped (its rotating damping then makes it unstable)."""
    import scipy.linalg as sla

    undecided = dict(UNDECIDED)
    try:
        linear = linearize(model, state)
    except (InvalidModelError, InvalidParameterError):
        return undecided
    stiffness = linear.stiffness
    if not np.all(np.isfinite(stiffness)):
        return undecided
    if _symmetric(stiffness):
        values = sla.eigvalsh(0.5 * (stiffness + stiffness.T))
        floor = NEUTRAL * float(np.max(np.abs(values), initial=0.0))
        unstable = int(np.sum(values < -floor))
        neutral = int(np.sum(np.abs(values) <= floor))
        stable: bool | None = unstable == 0
        if stable and neutral:
            stable = None
        if not unstable or _symmetric(linear.damping):
            # (a symmetric damping cannot hold a negative stiffness: Kelvin, Tait, Chetaev)
            return {
                "stable": stable,
                "unstable_directions": unstable,
                "neutral_directions": neutral,
            }
    if stiffness.shape[0] > EIGENVALUE_STABILITY_LIMIT:
        return undecided
    values = linear.eigenvalues()[0]
    growing = values[values.real > _zero_floor(values)]
    unstable = int(np.sum(growing.imag >= 0.0))  # a complex pair counted once
    neutral = linear.free_motions()
    stable = unstable == 0
    if stable and neutral:
        stable = None
    return {"stable": stable, "unstable_directions": unstable, "neutral_directions": neutral}


def _residual_bodies(layout: dict[str, Any], residual: Array, count: int = 3) -> list[str]:
    """Names of the bodies with the largest |residual| entries, largest first."""
    sizes = []
    for b in layout["bodies"]:
        if b["kind"] == "ground" or b["count"] == 0:
            continue
        part = residual[b["offset"] : b["offset"] + b["count"]]
        sizes.append((float(np.max(np.abs(part))), b["name"]))
    sizes.sort(reverse=True)
    return [name for size, name in sizes[:count] if size > 0]


def equilibrium(
    model: _core.Model | _core.System,
    time: float = 0.0,
    *,
    coordinates: Array | None = None,
    tolerance: float = 1e-10,
    max_iterations: int = 100,
    stable: bool | None = None,
    redundant_constraints: str = "remove",
) -> EquilibriumState:
    """Static equilibrium, or steady equilibrium under the prescribed motion of the drivers
    at `time`: every elastic coordinate at rest, the other coordinates moving as the drivers
    prescribe (the minimum-norm velocities and accelerations that satisfy the constraints;
    zero when nothing is driven, or when the drivers are at rest and do not accelerate at
    `time`, as a smooth motion profile at its start). Where a driver accelerates at `time`,
    the elastic coordinates also balance the inertia of that prescribed acceleration, so that
    a run started there has no elastic transient either. Gravity, loads, springs, elastic
    forces and the drivers' positions at `time` are in balance with the constraint forces;
    the multipliers of a driver are its static (or steady) effort. For a blade turned at
    constant speed by an angle driver this is the steadily rotating, centrifugally stretched
    blade.

    Returns an :class:`EquilibriumState` (a :class:`flexmbd.State`), which
    :func:`flexmbd.simulate` takes as ``initial_state`` to start without a transient.

    Newton's method on [M q_dd - F - Q_e + C_q^T lambda; C] = 0 for q and lambda with the
    matrix [[K, C_q^T], [C_q, 0]] (the dependence of the prescribed velocities on q is left
    out of the matrix, which then converges linearly when the motion is driven). Starts from
    `coordinates` or the model's initial coordinates; `coordinates` may be a `State`
    (``result.state(k)``), whose discrete variables then hold too: a spring wound past half
    a turn stays wound (from coordinates alone, its angles are taken in (-pi, pi]).
    Converged when the Newton increment is below `tolerance` (relative to the coordinates,
    at least 1). Raises
    :class:`flexmbd.errors.EquilibriumError` with the residual and the bodies that carry it
    when it does not converge, `InvalidModelError` when the stiffness matrix is singular.

    Newton's method finds any equilibrium, also an unstable one: from the horizontal, a
    double pendulum's iteration ends with both links upright. The state says which it found
    (``stable``, ``unstable_directions``: the stiffness at rest projected on the directions
    the constraints leave free, from the inertia of the Newton matrix; under a steady drive
    the linearization's stiffness, with the spin softening; with a nonsymmetric stiffness,
    the eigenvalues of the linearized motion: :class:`EquilibriumState`). `stable`:

    - None (default): when Newton's method ends in an unstable equilibrium, or fails (a
      singular or nearly singular start, such as a pendulum released horizontal), and no
      driver moves at `time`, it starts again from the same coordinates and seeks a stable
      one (as below); if it finds none, the unstable one is returned (and logged), or
      Newton's error raised. Under moving drivers the
      equilibrium is returned as found (a rotor's steady state may be held by its spin).
    - True: seek a stable equilibrium from the start; `EquilibriumError` if none is found.
    - False: the equilibrium Newton's method finds (to linearize about an inverted pendulum).

    The search for a stable equilibrium is Newton's method with the stiffness of the
    reference coordinates (positions and Euler parameters of the body frames) raised by a
    shift where the projected stiffness is not positive definite, so that each step goes
    down the potential, and with the body rotations limited to about 0.2 rad per iteration;
    near a stable equilibrium no shift is needed and the iteration is Newton's again.

    Redundant constraints (a shaft in two bearings, a planar mechanism of spatial joints)
    leave the multipliers not unique; `redundant_constraints` as in the runs' settings:
    ``"remove"`` (default) gives the redundant equations zero multipliers (the first bearing
    carries the whole load), ``"minimum-norm"`` the minimum-norm multipliers of the same
    constraint forces C_q^T lambda (the bearings of a symmetric shaft share it equally),
    ``"error"`` raises `InvalidModelError` naming the redundant joint equations.
    """
    model = _model(model)
    time = number(time, "time")
    coordinates, tolerance, max_iterations, discrete = _newton_options(
        model, coordinates, tolerance, max_iterations
    )
    if stable is not None and not isinstance(stable, bool):
        raise InvalidParameterError(f"stable: True, False or None, got {stable!r}", item="stable")
    if redundant_constraints not in REDUNDANCY:
        raise InvalidParameterError(
            f"redundant_constraints must be one of {', '.join(REDUNDANCY)}, got "
            f"{redundant_constraints!r}",
            item="redundant_constraints",
        )
    start = model.initial_coordinates if coordinates is None else coordinates
    unheld = unheld_frame_error(model, np.asarray(start, dtype=float), time, "Newton matrix")
    if unheld is not None:
        raise unheld  # (an equilibrium of such a body was found, and its modes were spurious)
    state = _equilibrium(model, time, coordinates, tolerance, max_iterations, stable, discrete)
    state = dataclasses.replace(state, system_identity=identity_of(model))
    return _redundancy_handled(model, state, redundant_constraints)


def _newton_options(
    model: _core.Model, coordinates: Any, tolerance: Any, max_iterations: Any
) -> tuple[Array | None, float, int, Array | None]:
    """The options of :func:`equilibrium`'s Newton iteration, checked: the starting
    `coordinates` (None, one finite number per coordinate of `model`, or a `State`, whose
    discrete variables come fourth), `tolerance` (a number above zero) and `max_iterations`
    (an integer, at least 1). An `InvalidParameterError` names the option."""
    tolerance = number(tolerance, "tolerance")
    if tolerance <= 0.0:
        raise InvalidParameterError(
            f"tolerance must be above zero (a relative Newton increment), got {tolerance:g}",
            item="tolerance",
        )
    max_iterations = integer(max_iterations, "max_iterations")
    if max_iterations < 1:
        raise InvalidParameterError(
            f"max_iterations must be at least 1, got {max_iterations}", item="max_iterations"
        )
    if coordinates is None:
        return None, tolerance, max_iterations, None
    discrete = None
    if isinstance(coordinates, State):
        # A recorded state's discrete variables: the springs stay wound (from its coordinates
        # alone, a pendulum settled at 5.67 rad on a spring was unwound to another
        # equilibrium 0.62 rad away).
        discrete = coordinates.discrete_for(model)
        coordinates = coordinates.coordinates
    q = numbers_array(coordinates, "coordinates")
    nq = model.coordinate_count
    if q.shape != (nq,):
        raise InvalidParameterError(
            f"coordinates must be {nq} numbers (the model's coordinates), got shape {q.shape}",
            item="coordinates",
        )
    bad = np.flatnonzero(~np.isfinite(q))
    if len(bad):
        raise InvalidParameterError(
            f"coordinates must be finite, got {q[bad[0]]} at index {bad[0]}", item="coordinates"
        )
    return q, tolerance, max_iterations, discrete


#: Choices of `redundant_constraints` of :func:`equilibrium` (the runs' names).
REDUNDANCY = ("remove", "minimum-norm", "error")


def _redundancy_handled(
    model: _core.Model, state: EquilibriumState, handling: str
) -> EquilibriumState:
    """`state` with the multipliers of redundant constraint equations as `handling` asks (see
    :func:`equilibrium`): as they are ("remove": those of the left-out rows are 0), the
    minimum-norm multipliers of the same constraint forces C_q^T lambda (truncated SVD at
    RANK_TOLERANCE, as the runs' "minimum-norm"), or an error naming the redundant rows."""
    nq, nc = model.coordinate_count, model.constraint_count
    if handling == "remove" or nc == 0:
        return state
    ev = model.evaluate(
        state.time,
        state.coordinates,
        state.velocities,
        state.accelerations,
        state.multipliers,
        mass=1.0,
        discrete=state.discrete,
    )
    matrix = _matrix(ev)
    if handling == "error":
        kept = _independent_rows(matrix, nq, np.arange(nc))
        redundant = np.setdiff1d(np.arange(nc), kept)
        if len(redundant):
            joints, equations = _row_names(model.describe(), redundant)
            raise InvalidModelError(
                f"equilibrium: {len(redundant)} redundant constraint equation"
                f"{'s' if len(redundant) > 1 else ''} (redundant_constraints='error'): {equations}",
                item=joints[0] if joints else None,
            )
        return state
    transpose = matrix[nq:, :nq].toarray().T
    spread = np.linalg.lstsq(transpose, transpose @ state.multipliers, rcond=RANK_TOLERANCE)[0]
    return dataclasses.replace(state, multipliers=spread)


def _equilibrium(
    model: _core.Model,
    time: float,
    coordinates: Array | None,
    tolerance: float,
    max_iterations: int,
    stable: bool | None,
    discrete: Array | None = None,
) -> EquilibriumState:
    """:func:`equilibrium` after its arguments were checked, the redundant rows' multipliers
    as Newton's method leaves them (0)."""
    layout = model.describe()
    q = np.array(model.initial_coordinates if coordinates is None else coordinates, dtype=float)
    q = _turned_to_drivers(model, time, q, layout)
    _check_drivers_at_start(model, time, q, layout)
    if stable:
        return _solve_equilibrium(
            model, time, q, layout, tolerance, max_iterations, seek=True, discrete=discrete
        )
    try:
        state = _solve_equilibrium(
            model, time, q.copy(), layout, tolerance, max_iterations, discrete=discrete
        )
    except (InvalidModelError, EquilibriumError) as failure:
        # A direction without stiffness at the start (a rigid pendulum released from the
        # horizontal: a singular matrix), or nearly without (a flexible one, whose elastic
        # coupling leaves a tiny pivot: Newton's first step is huge and it diverges): the
        # search's shift gives it some.
        if stable is not None:
            raise
        try:
            return _solve_equilibrium(
                model, time, q, layout, tolerance, max_iterations, seek=True, discrete=discrete
            )
        except (EquilibriumError, InvalidModelError) as second:
            # A fault of the model (inconsistent joints) found by the search outweighs the
            # first iteration's failure to converge.
            if isinstance(second, InvalidModelError) and not isinstance(failure, InvalidModelError):
                raise second from None
            if getattr(second, "still_moving", False) and isinstance(failure, EquilibriumError):
                # On its way where Newton's method diverged: more iterations, not another
                # start. (A singular start, a free body, keeps its own error.)
                raise second from None
            raise failure from None
    if stable is None and state.stable is False and not np.any(state.velocities != 0.0):
        try:
            return _solve_equilibrium(
                model, time, q, layout, tolerance, max_iterations, seek=True, discrete=discrete
            )
        except EquilibriumError as error:
            _log.warning(
                "equilibrium: found an unstable equilibrium (%d unstable directions) and no "
                "stable one from the starting coordinates (%s)",
                state.unstable_directions,
                error,
            )
    return state


def _solve_equilibrium(
    model: _core.Model,
    time: float,
    q: Array,
    layout: dict[str, Any],
    tolerance: float = 1e-10,
    max_iterations: int = 100,
    seek: bool = False,
    discrete: Array | None = None,
    stability: bool = True,
) -> EquilibriumState:
    """Newton's method of :func:`equilibrium` from `q` (the drivers checked at `time`); with
    `seek`, the search for a stable equilibrium described there. `discrete`: the discrete
    variables at `q` (a recorded state's), else those of `q`. Without `stability`, a state
    whose stability needs the linearization (moving, or a nonsymmetric stiffness) is left
    undecided (None)."""

    flexible = model.flexible_bodies
    nq, nc = model.coordinate_count, model.constraint_count
    rigid = ~_elastic_mask(layout)
    rotations = _euler_parameter_mask(layout)
    lam = _static_multipliers(model, time, q, rigid)
    kept_rows = np.arange(nc)
    scale = max(1.0, float(np.max(np.abs(q))))
    step = np.inf
    residual = np.zeros(nq + nc)
    kept_factors: dict[int, tuple[sp.csr_matrix, Any]] = {}
    steps: list[float] = []
    residuals: list[float] = []
    # The discrete variables follow the iterates as a run's follow its steps: a spring whose
    # rest angle is beyond half a turn was unwrapped against its starting angle, never
    # reached its rest angle and Newton's method diverged.
    discrete = model.discrete_variables(time, q, np.zeros(nq), discrete)
    for iteration in range(1, max_iterations + 1):
        qd, qdd = _prescribed_rates(model, time, q, rigid)
        if iteration > 1:
            discrete = model.discrete_variables(time, q, qd, discrete)
        ev = model.evaluate(time, q, qd, qdd, lam, position=1.0, discrete=discrete)
        residual = ev["residual"]
        matrix = _matrix(ev)
        # The unknowns of the Newton solve: the coordinates and the multipliers of the rows
        # kept at this iterate (those of redundant rows 0, as the runs' "remove" does; which
        # rows are redundant may change as the mechanism moves, as Bricard's does).
        rows = _independent_rows(matrix, nq, kept_rows)
        if not np.array_equal(rows, kept_rows):
            lam = _moved_multipliers(matrix, nq, lam, rows)
            kept_rows = rows
            ev = model.evaluate(time, q, qd, qdd, lam, position=1.0, discrete=discrete)
            residual = ev["residual"]
            matrix = _matrix(ev)
        unknowns = np.concatenate([np.arange(nq), nq + kept_rows])
        matrix = _kept(matrix, unknowns)
        truncated = False
        if seek:
            matrix = _shifted_to_stable(matrix, nq, layout, rigid, kept_factors)
        delta = np.zeros(nq + nc)
        # Already in balance (a probe in free flight, nothing acting): nothing to solve,
        # though the free directions make the matrix singular. Not in the search for a stable
        # equilibrium, whose shifted steps leave a balanced saddle (the spatial four-bar's
        # start) by growing along its unstable direction.
        if seek or float(np.max(np.abs(residual[unknowns]), initial=0.0)) > BALANCED:
            delta[unknowns] = _newton_solve(
                matrix, -residual[unknowns], layout, flexible, kept_factors
            )
        if not np.all(np.isfinite(delta)):
            if iteration == 1:
                free, item, directions = _free_motions(matrix, q, nq, layout, kept_factors)
                message = f"equilibrium: the stiffness matrix is singular: {free}"
                if directions:
                    raise FreeMotionError(message, item=item, directions=directions)
                raise InvalidModelError(message, item=item)
            # Singular at an iterate far from the start: the iteration diverged there.
            bodies = _residual_bodies(layout, residual[:nq])
            raise EquilibriumError(
                f"equilibrium: no convergence (Newton's matrix singular at iteration "
                f"{iteration}, where the residual is largest in bodies {', '.join(bodies)})",
                residual=float(np.max(np.abs(residual))),
                bodies=bodies,
                time=time,
            )
        if seek:
            turn = float(np.max(np.abs(delta[:nq][rotations]), initial=0.0))
            if turn > SEEK_TURN_LIMIT:
                delta *= SEEK_TURN_LIMIT / turn
                truncated = True
        q += delta[:nq]
        lam += delta[nq:]
        step = float(np.max(np.abs(delta[:nq]))) / scale
        steps.append(step)
        residuals.append(float(np.max(np.abs(residual[unknowns]), initial=0.0)))
        if step <= tolerance and not truncated:
            qd, qdd = _prescribed_rates(model, time, q, rigid)
            discrete = model.discrete_variables(time, q, qd, discrete)
            final = model.evaluate(time, q, qd, qdd, lam, position=1.0, discrete=discrete)
            violated = _violated_rows(final["residual"][nq:], kept_rows, scale * tolerance)
            if len(violated):
                # Rows left out as dependent on the kept ones (which `_independent_rows`
                # would have taken back had they become independent) and not met with them:
                # joints that repeat each other's equations with other values.
                joints, equations = _row_names(layout, violated)
                raise InvalidModelError(
                    "equilibrium: constraint equations that repeat others but are not met "
                    f"where those are (inconsistent joints, |C| up to "
                    f"{np.max(np.abs(final['residual'][nq + violated])):.3e}): {equations}",
                    item=joints[0] if joints else None,
                )
            newton = _kept(_matrix(final), unknowns)
            inertia = _inertia(newton, nq, layout, kept_factors)
            unstable, neutral = (None, 0) if inertia is None else inertia
            if seek and unstable:
                continue  # a saddle reached exactly: the shift pushes off it
            stable = None if unstable is None else unstable == 0
            if stable and neutral:
                stable = None  # no stiffness in some directions: not decided at this order
            state = EquilibriumState(
                time,
                q,
                qd,
                qdd,
                lam,
                layout=layout,
                flexible=flexible,
                iterations=iteration,
                residual=float(np.max(np.abs(final["residual"]))),
                stable=stable,
                unstable_directions=unstable or 0,
                neutral_directions=neutral,
                discrete=discrete,
            )
            # Newton's matrix is the stiffness in the coordinates q at fixed velocities: under
            # a steady drive it leaves out the spin softening of the turning frames (a
            # pendulum on a turntable spun above sqrt(g / L) was called stable), and its
            # symmetric part does not decide a nonsymmetric (follower-load) stiffness.
            moving = bool(np.any(qd != 0.0))
            if moving or not _symmetric(newton[:nq, :nq]):
                fields = _linearized_stability(model, state) if stability else UNDECIDED
                state = dataclasses.replace(state, **fields)
            return state
    bodies = _residual_bodies(layout, residual[:nq])
    largest = float(np.max(np.abs(residual))) if len(residual) else 0.0
    what = " to a stable equilibrium" if seek else ""
    moving = ""
    last, falling = steps[-5:], residuals[-10:]
    converging = len(last) == 5 and all(np.diff(last) <= 0.0) and last[-1] < last[0]
    # (turning by the limit with the residual falling steadily: a free body pushed by a load
    # turns by the limit too, its residual the same)
    descending = (
        truncated
        and len(falling) == 10
        and all(np.diff(falling) < 0.0)
        and falling[-1] < 0.9 * falling[0]
    )
    if seek and (converging or descending):
        # Converging, or turning the bodies by the limit per iteration towards the balance:
        # on its way, not diverging (a spring whose rest angle is 20 rad away takes about
        # 100 iterations).
        moving = (
            f": it was on its way (bodies turned by at most about {2 * SEEK_TURN_LIMIT:g} rad "
            "per iteration, the residual falling); raise max_iterations"
        )
    error = EquilibriumError(
        f"equilibrium: no convergence{what} in {max_iterations} iterations (last relative "
        f"increment {step:.2e}, residual {largest:.3e}, largest in bodies "
        f"{', '.join(bodies) or 'none'}){moving}",
        residual=largest,
        bodies=bodies,
        time=time,
    )
    error.still_moving = bool(moving)  # type: ignore[attr-defined]
    raise error


def steady_rotation(
    model: _core.Model | _core.System, time: float = 0.0, **options: Any
) -> EquilibriumState:
    """The steady rotation of a rotor at `time`: the drivers turn at their speed at `time`
    (at least one must turn, none may accelerate), the elastic coordinates are at rest in the
    centrifugally stretched (and gravity-loaded) state, with the velocities of that spin:
    the bodies a driver carries (joined to its driven body by other joints, as a bob on a free
    hinge of a turning hub) move rigidly with the driven body, the others rest. This is
    :func:`equilibrium` with its preconditions checked; `options` are its options
    (``coordinates``, ``tolerance``, ``max_iterations``, ``redundant_constraints``).
    Raises `InvalidModelError` naming the driver that accelerates, or when nothing turns."""
    return _steady_rotation(_model(model), time, options)


def _steady_rotation(
    model: _core.Model, time: float, options: dict[str, Any], stability: bool = True
) -> EquilibriumState:
    """:func:`steady_rotation`; without `stability` the state's stability fields are not
    determined (None: a linearization saved where the caller linearizes anyway)."""
    time = number(time, "time")
    nq, nc = model.coordinate_count, model.constraint_count
    unknown = sorted(set(options) - set(STEADY_OPTIONS))
    if unknown:
        raise InvalidParameterError(
            f"steady_rotation: unknown option {unknown[0]!r}; options: {', '.join(STEADY_OPTIONS)}",
            item=unknown[0],
        )
    coordinates, tolerance, max_iterations, discrete = _newton_options(
        model,
        options.get("coordinates"),
        options.get("tolerance", 1e-10),
        options.get("max_iterations", 100),
    )
    handling = options.get("redundant_constraints", "remove")
    if handling not in REDUNDANCY:
        raise InvalidParameterError(
            f"redundant_constraints must be one of {', '.join(REDUNDANCY)}, got {handling!r}",
            item="redundant_constraints",
        )
    q = np.array(model.initial_coordinates if coordinates is None else coordinates, dtype=float)
    zero_q, zero_l = np.zeros(nq), np.zeros(nc)
    layout = model.describe()
    q = _turned_to_drivers(model, time, q, layout)
    _check_drivers_at_start(model, time, q, layout)
    ev = model.evaluate(time, q, zero_q, zero_q, zero_l)
    drivers = [j for j in layout["joints"] if "driver" in j["type"]]
    rows = {j["name"]: range(j["row"], j["row"] + len(j["equations"])) for j in drivers}
    turning = [name for name, r in rows.items() if np.any(ev["constraint_rate"][list(r)] != 0)]
    if not turning:
        raise InvalidModelError(
            f"steady rotation: no driver moves at t = {time}; use equilibrium for a static state",
            item="drivers",
        )
    # At rest, gamma of a driver row is its -C_tt: for an angle driver, C = sin(theta - f),
    # -C_tt = f'^2 C + cos(theta - f) f'' (C_t = -cos(theta - f) f'): its acceleration is
    # gamma - C_t^2 C, where the residual C of a run's coordinates (1e-11), times f'^2,
    # counted as an acceleration at 1000 rad/s. (A translation driver's -C_tt is f''.)
    gamma, rate = ev["gamma"], ev["constraint_rate"]
    acceleration = gamma - rate**2 * ev["residual"][nq:]
    floor = 1e-12 * max(1.0, float(np.max(np.abs(gamma)))) + 1e-10 * rate**2
    for name, r in rows.items():
        if np.any(np.abs(acceleration[list(r)]) > floor[list(r)]):
            raise InvalidModelError(
                f"steady rotation: driver '{name}' accelerates at t = {time}; a steady rotation "
                "needs constant driver speeds (start later, or use equilibrium)",
                item=f"driver '{name}'",
            )
    state = _solve_equilibrium(
        model, time, q, layout, tolerance, max_iterations, discrete=discrete, stability=stability
    )
    state = dataclasses.replace(state, system_identity=identity_of(model))
    return _redundancy_handled(model, state, handling)


#: The options of :func:`steady_rotation` (those of :func:`equilibrium` that apply).
STEADY_OPTIONS = ("coordinates", "tolerance", "max_iterations", "redundant_constraints")


@dataclass
class LinearizedSystem:
    """The motion linearized about a state, in the independent directions of the constraints:
    mass @ z_dd + damping @ z_dot + stiffness @ z = 0 with q = q0 + basis @ z. `damping`
    holds the gyroscopic terms, `stiffness` the centrifugal softening, the geometric stiffness
    and the constraint-force terms."""

    mass: Array
    damping: Array
    stiffness: Array
    basis: Array
    state: EquilibriumState
    _eigen: tuple[Array, Array] | None = field(default=None, repr=False)
    #: Generalized forces of the inputs (coordinates x inputs) and their names.
    input_forces: Array | None = field(default=None, repr=False)
    input_names: list[str] = field(default_factory=list, repr=False)
    #: Output rows dy/dq (outputs x coordinates) and their names.
    output_rows: Array | None = field(default=None, repr=False)
    output_names: list[str] = field(default_factory=list, repr=False)
    #: Absolute accuracy of `stiffness` and `damping` (entries), set by the central
    #: differences of the moving basis (:data:`BASIS_ACCURACY` times the size of its terms;
    #: 0 at rest): directions with K z and D z below it are free motions.
    accuracy: float = field(default=0.0, repr=False)

    def state_space(self) -> StateSpace:
        """The state-space model x_dot = A x + B u, y = C x + D u with x = (z, z_dot) of the
        inputs and outputs given to :func:`linearize` (:mod:`flexmbd.state_space`)."""
        n = self.mass.shape[0]
        minv = np.linalg.inv(self.mass)
        zero, one = np.zeros((n, n)), np.eye(n)
        a = np.block([[zero, one], [-minv @ self.stiffness, -minv @ self.damping]])
        nq = self.basis.shape[0]
        forces = np.zeros((nq, 0)) if self.input_forces is None else self.input_forces
        b = np.vstack([np.zeros((n, forces.shape[1])), minv @ (self.basis.T @ forces)])
        rows = np.zeros((0, self.basis.shape[0])) if self.output_rows is None else self.output_rows
        c = np.hstack([rows @ self.basis, np.zeros((rows.shape[0], n))])
        d = np.zeros((c.shape[0], b.shape[1]))
        return StateSpace(a, b, c, d, list(self.input_names), list(self.output_names))

    def eigenvalues(self) -> tuple[Array, Array]:
        """Eigenvalues s (1/s) of the first-order form, sorted by |Im s| then Re s, and the
        mode shapes in the coordinates q (columns). The motions with neither stiffness nor
        damping (K z = D z = 0: the rigid-body motions of a free structure) are taken out
        first, each an exact double zero: in the first-order matrix such a pair is defective,
        and LAPACK returned it as +-sqrt(eps |A|), about 1e-7 (a free torsional pair counted 5
        free motions and a mode of 1e-8 Hz). Sets of coordinates that M, D and K do not couple
        (bodies without a joint or force between them, a straight beam's axial and bending
        motions) are solved apart, each on its own scale (:func:`_decoupled_blocks`)."""
        if self._eigen is None:
            n = self.mass.shape[0]
            matrices = (self.mass, self.damping, self.stiffness)
            # Free motions: within the accuracy of the entries, or within round-off of the
            # largest entry of the whole model (a subsystem's own 1e-11 of its largest
            # would keep a residue of round-off in a stiffness-free body).
            floor = self.accuracy
            if n and np.all(np.isfinite(self.stiffness)) and np.all(np.isfinite(self.damping)):
                largest = max(
                    float(np.max(np.abs(self.stiffness))), float(np.max(np.abs(self.damping)))
                )
                floor = max(floor, ROUND_OFF_FREE * largest)
            blocks = _decoupled_blocks(*matrices)
            if len(blocks) == 1:
                all_values, all_shapes = _subsystem_eigen(*matrices, floor)
            else:
                values, shapes = [], []
                for block in blocks:
                    part = np.ix_(block, block)
                    found, vectors = _subsystem_eigen(*(a[part] for a in matrices), floor)
                    embedded = np.zeros((n, vectors.shape[1]), complex)
                    embedded[block] = vectors
                    values.append(found)
                    shapes.append(embedded)
                all_values, all_shapes = np.concatenate(values), np.hstack(shapes)
            order = np.lexsort((all_values.real, np.abs(all_values.imag)))
            self._eigen = (all_values[order], self.basis @ all_shapes[:, order])
        return self._eigen

    def without_velocity_terms(self) -> LinearizedSystem:
        """The same linearization with the velocity-dependent terms (Coriolis coupling,
        gyroscopic moments, damping) left out: D = 0."""
        return LinearizedSystem(
            self.mass,
            np.zeros_like(self.damping),
            self.stiffness,
            self.basis,
            self.state,
            input_forces=self.input_forces,
            input_names=self.input_names,
            output_rows=self.output_rows,
            output_names=self.output_names,
            accuracy=self.accuracy,
        )

    def oscillating(
        self, relative_floor: float = EIGEN_ROUND_OFF
    ) -> tuple[Array, Array, NDArray[np.complex128]]:
        """The oscillating modes (one per pair of complex eigenvalues s, Im s > 0), by
        frequency: damped frequencies Im s / 2 pi (Hz), damping ratios -Re s / |s| and the
        complex shapes in q (columns). Pairs with Im s at most `relative_floor` times the
        largest |s| (at least 1) are left out: the rounding of a rigid-body mode's double zero
        makes such a pair. With 0, every pair with Im s > 0 is kept (LAPACK gives real
        eigenvalues of the real first-order matrix exactly real): a rotor's forward whirl
        seen from the rotating frame near its critical speed, where its frequency there nears
        zero while the stiff modes of a nearly massless damped shaft make |s| large."""
        relative_floor = _floor(relative_floor)
        values, vectors = self.eigenvalues()
        keep = np.flatnonzero(values.imag > _zero_floor(values, relative_floor))
        keep = keep[np.argsort(values[keep].imag, kind="stable")]
        s = values[keep]
        # + 0.0: an undamped mode's ratio is 0, not -0 (-Re s of Re s = 0).
        return s.imag / (2.0 * np.pi), -s.real / np.abs(s) + 0.0, vectors[:, keep]

    def free_motions(self, relative_floor: float = EIGEN_ROUND_OFF) -> int:
        """How many independent motions have neither stiffness nor damping: the rigid-body
        modes of a free-flying structure (six for a free body, one for a wheel on a free
        axle), each a double zero eigenvalue. Eigenvalues of modulus at most `relative_floor`
        times the largest (at least 1) count as zero, as in :meth:`oscillating`
        (:func:`_zero_floor`)."""
        relative_floor = _floor(relative_floor)
        values, _ = self.eigenvalues()
        return int(np.sum(np.abs(values) <= _zero_floor(values, relative_floor))) // 2

    def frequencies(self) -> Array:
        """Damped natural frequencies (Hz) of the oscillating modes, ascending (one per pair
        of complex eigenvalues)."""
        return self.oscillating()[0]

    def modes(self) -> tuple[Array, Array]:
        """Frequencies (Hz) and mode shapes (real parts of the eigenvectors in q, columns) of
        the oscillating modes."""
        freq, _, shapes = self.oscillating()
        # Rotate each complex shape so that its largest entry is real.
        peak = shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])]
        return freq, np.real(shapes / (peak / np.abs(peak)))


def _zero_floor(values: NDArray[np.complex128], relative: float = EIGEN_ROUND_OFF) -> float:
    """`relative` times the largest |s| of `values` (at least 1): the size below which an
    eigenvalue is zero, or its real part no growth."""
    return relative * max(1.0, float(np.max(np.abs(values), initial=0.0)))


#: Entries of M, D or K at most this fraction of sqrt(r_i r_j) (r_i the largest |entry| of
#: row i of that matrix) couple nothing in :func:`_decoupled_blocks`: the round-off left of an
#: exact zero (6e-33 between a pendulum's and a beam's rows of M against 0.5).
DECOUPLED = 1e-14

#: Singular values of [K; D] at most this fraction of the largest entry of the whole model's
#: K and D are free motions in every decoupled subsystem (:data:`FREE_DIRECTION` being
#: relative to the subsystem's own largest): 45 eps, round-off of the model's largest terms.
ROUND_OFF_FREE = 1e-14


def _decoupled_blocks(*matrices: Array) -> list[NDArray[np.int64]]:
    """The independent coordinates of each subsystem that `matrices` (n x n each: M, D, K)
    do not couple to the rest, as index arrays (connected components of their entries above
    :data:`DECOUPLED`), or one block of all when an entry is not finite. Block-diagonal
    M, D and K have the union of the blocks' eigenvalues, and each block solved apart keeps
    its own scale: in one problem a clamped steel beam's stiffness (largest singular value
    5e9) set the free motions' threshold (1e-11 of it, 0.05) above the 0.038 of Ziegler's
    follower-loaded pendulum beside it, whose flutter (+-0.151 +-0.219i) came out as a free
    motion and +-0.224i. (A diagonal scaling of [K; D] instead would raise a free body's rows
    of round-off to a stiffness; LAPACK's balancing already gives the pendulum's eigenvalues
    to 2e-10 in one first-order matrix with the beam once no direction is taken out.)"""
    n = matrices[0].shape[0]
    if n < 2 or not all(np.all(np.isfinite(a)) for a in matrices):
        return [np.arange(n)]
    linked = np.zeros((n, n), dtype=bool)
    for matrix in matrices:
        if not np.any(matrix):
            continue  # (no damping)
        size = np.abs(matrix)
        root = np.sqrt(np.max(size, axis=1))
        linked |= size > np.outer(DECOUPLED * root, root)
    linked |= linked.T
    # Each block: the coordinates reached from its first one through linked entries.
    blocks, unreached = [], np.ones(n, dtype=bool)
    while np.any(unreached):
        block = np.zeros(n, dtype=bool)
        block[int(np.argmax(unreached))] = True
        frontier = block.copy()
        while np.any(frontier):
            frontier = np.any(linked[frontier], axis=0) & ~block
            block |= frontier
        unreached &= ~block
        blocks.append(np.flatnonzero(block))
    return blocks


def _subsystem_eigen(m: Array, d: Array, k: Array, accuracy: float) -> tuple[Array, Array]:
    """The eigenvalues of M z_dd + D z_dot + K z = 0 and the z part of the first-order
    eigenvectors (n x 2 n, unit [z; s z] as LAPACK's): the free directions (singular values
    of [K; D] within `accuracy` or :data:`FREE_DIRECTION` of the largest) as exact double
    zeros, the rest by :func:`_undamped_eigen` or the first-order matrix."""
    import scipy.linalg as sla

    free = _free_directions(k, d, accuracy)
    # The rest: the M-orthogonal complement of the free directions, decoupled from them
    # where K and D are symmetric or skew (their rows N^T K = N^T D = 0 too).
    rest = sla.null_space((m @ free).T) if free.shape[1] else None
    if rest is not None:
        m, d, k = (rest.T @ a @ rest for a in (m, d, k))
    r = m.shape[0]
    found = _undamped_eigen(m, d, k) if r else None
    if found is not None:
        values, vectors = found
    elif r:
        minv_k = np.linalg.solve(m, k)
        minv_d = np.linalg.solve(m, d)
        a = np.block([[np.zeros((r, r)), np.eye(r)], [-minv_k, -minv_d]])
        values, vectors = sla.eig(a)
    else:
        values, vectors = np.zeros(0, complex), np.zeros((0, 0))
    values = np.concatenate([np.zeros(2 * free.shape[1], dtype=complex), values])
    moving = vectors[:r] if rest is None else rest @ vectors[:r]
    return values, np.hstack([free, free, moving]).astype(complex)


#: Singular values of [K; D] below this fraction of the largest are the free motions of
#: :meth:`LinearizedSystem.eigenvalues` (a free body's are round-off, 1e-16 relative).
FREE_DIRECTION = 1e-11


def _free_directions(stiffness: Array, damping: Array, accuracy: float = 0.0) -> Array:
    """An orthonormal basis (n, r) of the directions z with K z = 0 and D z = 0: the
    singular values of [K; D] at most :data:`FREE_DIRECTION` of the largest, or at most
    `accuracy` (that of the entries of K and D: the moving basis' differences leave a
    spinning rotor's cyclic spin angle a residue of 4e-5 against stiffnesses of 2e5, which
    came out as a mode of 0.015 rad/s, or a sleeping top's as a false instability)."""
    import scipy.linalg as sla

    n = stiffness.shape[0]
    # (Without damping [K; 0] has K's singular vectors; the vectors only where some value
    # is small: the full SVD of [K; D] took 4 of the 10 s of an 1,800-coordinate solid.)
    stacked = np.vstack([stiffness, damping]) if np.any(damping) else stiffness
    if n == 0 or not np.all(np.isfinite(stacked)):
        return np.zeros((n, 0))
    values = sla.svdvals(stacked)
    largest = float(values[0]) if len(values) else 0.0
    if largest == 0.0:
        return np.eye(n)
    rank = int(np.sum(values > max(FREE_DIRECTION * largest, accuracy)))
    if rank == n:
        return np.zeros((n, 0))
    _, values, rows = sla.svd(stacked, full_matrices=False)
    rank = int(np.sum(values > max(FREE_DIRECTION * largest, accuracy)))
    return rows[rank:].T.copy()


#: Largest action |K_skew phi| of the skew part of the stiffness on a mode phi, relative to
#: |K phi| (or w^2 |M phi|), for which :func:`_undamped_eigen` solves the symmetric problem.
SKEW_ON_MODES = 1e-6


def _undamped_eigen(m: Array, d: Array, k: Array) -> tuple[Array, Array] | None:
    """The eigenvalues and first-order eigenvectors [phi; s phi] (unit length, as LAPACK's)
    of M z_dd + K z = 0 from a symmetric generalized problem, when D is zero and M and K
    are symmetric (within :data:`NEUTRAL`); None otherwise (the general first-order
    problem). With K positive definite, M phi = mu K phi (mu = 1 / w^2, s = +-i w): its
    largest mu, the lowest modes, come out to round-off of themselves, where the direct
    problem split a rotor's first pair by 4e-7 (K's condition number 1e11); else, with M
    positive definite, K phi = w^2 M phi (s = +-i w, or +-sqrt(-w^2) where w^2 < 0). Both
    diagonally scaled to unit diagonal. The vectors are the first-order ones' z part only
    (n x 2 n), which is all :meth:`LinearizedSystem.eigenvalues` reads. The symmetric
    problem of n takes a fraction of the time of the nonsymmetric one of 2 n: an
    1,800-coordinate solid's frequencies took 132 s. In the inverted problem the highest
    modes' shapes are less accurate (a 12-element strip's: residuals of 2e-7 of K phi
    against 9e-9); their w^2, Rayleigh quotients, are within 6e-11 of the FE model's."""
    import scipy.linalg as sla

    if np.any(d) or not (_symmetric(m) and _symmetric(k)):
        return None
    skew = 0.5 * (k - k.T)
    m, k = 0.5 * (m + m.T), 0.5 * (k + k.T)

    def scaled(matrix: Array) -> Array:
        diagonal = np.abs(np.diag(matrix))
        return np.where(diagonal > 0.0, 1.0 / np.sqrt(np.where(diagonal > 0, diagonal, 1)), 1.0)

    try:
        scale = scaled(k)
        mu, psi = sla.eigh(scale[:, None] * m * scale, scale[:, None] * k * scale)
        if not np.all(mu > 0.0):
            return None  # M not positive definite
        phi = scale[:, None] * psi
        # w^2 as the Rayleigh quotients of the shapes: 1 / mu of the highest modes was off by
        # 2e-9 (their mu near round-off of the largest), the quotients by 6e-11.
        squares = np.einsum("ij,ij->j", phi, k @ phi) / np.einsum("ij,ij->j", phi, m @ phi)
    except (sla.LinAlgError, ValueError):  # K not positive definite
        try:
            scale = scaled(m)
            squares, psi = sla.eigh(scale[:, None] * k * scale, scale[:, None] * m * scale)
            phi = scale[:, None] * psi
        except (sla.LinAlgError, ValueError):
            return None  # M not positive definite
    # The skew part left out must be negligible on every mode, not only against the largest
    # entries: in independent coordinates that mix a stiff body's with a follower-loaded
    # pendulum's, its 0.3 hid under the body's 2.6e9 (Ziegler's flutter came out as a
    # divergence). Else the general problem.
    acting = np.linalg.norm(skew @ phi, axis=0)
    size_of = np.maximum(
        np.linalg.norm(k @ phi, axis=0), np.abs(squares) * np.linalg.norm(m @ phi, axis=0)
    )
    if np.any(acting > SKEW_ON_MODES * size_of):
        return None
    rates = np.sqrt(np.abs(squares))
    roots = np.where(squares >= 0.0, 1j * rates, rates + 0j)  # i w, or a real rate
    values = np.concatenate([roots, -roots])
    # The z part of the unit [phi; s phi] (all that the caller reads): |phi| sqrt(1 + |s|^2).
    size = np.linalg.norm(phi, axis=0)
    shapes = np.hstack([phi, phi]) / np.concatenate([size, size])[None, :]
    return values, (shapes / np.sqrt(1.0 + np.abs(values) ** 2)[None, :]).astype(complex)


def _floor(value: Any) -> float:
    """The `relative_floor` of :meth:`LinearizedSystem.oscillating`: a finite number, at
    least 0."""
    value = number(value, "relative_floor")
    if value < 0.0:
        raise InvalidParameterError(
            f"relative_floor must be at least 0, got {value:g}", item="relative_floor"
        )
    return value


#: Choices of the independent coordinates of :func:`linearize`.
INDEPENDENT = ("elastic", "null-space")

#: The turn (rad) of the fastest reference coordinate over the step of the central
#: differences of :func:`moving_basis`: truncation (its square) and round-off (1e-16 over its
#: square) both near 1e-8 relative.
BASIS_TURN = 1e-4

#: Accuracy of the moving basis' terms of the linearization (D B_dot + M B_dd in the
#: stiffness, 2 M B_dot in the damping), relative to their largest entry: 100 times the
#: 1e-8 of :data:`BASIS_TURN` (a spinning rotor's spin column came out at 1e-8 of them).
BASIS_ACCURACY = 100.0 * BASIS_TURN**2


def _constraint_jacobian(model: _core.Model, time: float, q: Array) -> Array:
    """C_q (constraint rows x coordinates), dense."""
    nq, nc = model.coordinate_count, model.constraint_count
    zero = np.zeros(nq)
    return _matrix(model.evaluate(time, q, zero, zero, np.zeros(nc), mass=1.0))[nq:, :nq].toarray()


def _dependent_columns(cq: Array, elastic: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Columns of C_q for the dependent coordinates, as many as its rank: pivoted among the
    reference coordinates first (QR with column pivoting), then among the elastic ones for
    the rank the reference coordinates leave."""
    import scipy.linalg as sla

    if cq.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    scale = max(1.0, float(np.max(np.abs(cq))))
    tolerance = 1e-10 * scale
    chosen: list[int] = []
    remaining = cq
    for group in (np.flatnonzero(~elastic), np.flatnonzero(elastic)):
        if len(group) == 0:
            continue
        _, r, pivots = sla.qr(remaining[:, group], mode="economic", pivoting=True)
        rank = int(np.sum(np.abs(np.diag(r)) > tolerance))
        chosen.extend(group[pivots[:rank]])
        if rank:
            q, _ = np.linalg.qr(cq[:, chosen])
            remaining = cq - q @ (q.T @ cq)
    return np.array(chosen, dtype=np.int64)


def _frame_transform(
    layout: dict[str, Any], q: Array, spinning: frozenset[int] = frozenset()
) -> tuple[Array, NDArray[np.bool_]]:
    """The map T(q) (coordinates x local coordinates) from the local coordinates y of a
    change of q to the change dq = T y, and the mask of the elastic ones among y. A body
    frame's y are the change of its origin and the small rotation, both in the frame's own
    axes: dR = A(p) dR_bar and dp = 1/2 G(p)^T dpi_bar, so a frame has six y for its seven
    q (the Euler parameters' norm is left out); elastic coordinates and point masses keep
    theirs. About a steady rotation the local coordinates see the motion from the turning
    frames, where it does not depend on time; an Euler parameter turns at half the rate, and
    taken as a coordinate of the motion it put Omega^2 / 4 into a hinged blade's squared
    frequency. The bodies in `spinning` (:func:`_spinning_bodies`: a symmetric rotor
    spinning on its axis relative to everything it is joined to) take global axes instead,
    dR and dp = 1/2 E(p)^T dpi: seen from their own turning frame, the gimbals that hold
    such a rotor turn, and their equations were periodic."""
    nq = layout["coordinate_count"]
    frames = [b["kind"] in ("rigid", "flexible") and b["count"] >= 7 for b in layout["bodies"]]
    transform = np.zeros((nq, nq - sum(frames)))
    elastic = np.zeros(transform.shape[1], dtype=bool)
    column = 0
    for index, (b, frame) in enumerate(zip(layout["bodies"], frames, strict=True)):
        offset, count = b["offset"], b["count"]
        if frame:
            block = _frame_block(q[offset + 3 : offset + 7], index in spinning)
            transform[offset : offset + 7, column : column + 6] = block
            column += 6
        rest = count - 7 if frame else count
        first = offset + count - rest
        transform[first : first + rest, column : column + rest] = np.eye(rest)
        elastic[column : column + rest] = b["kind"] == "flexible"
        column += rest
    return transform, elastic


def _frame_block(p: Array, global_axes: bool) -> Array:
    """The (7, 6) map from a frame's change of origin and small rotation to the change of its
    coordinates [R, p]: in its own axes (dR = A(p) dR_bar, dp = 1/2 G(p)^T dpi_bar), or with
    `global_axes` in global ones (dR, dp = 1/2 E(p)^T dpi)."""
    frame = "global" if global_axes else "body"
    block = np.zeros((7, 6))
    block[:3, :3] = np.eye(3) if global_axes else euler_parameters_to_matrix(p)
    block[3:, 3:] = np.column_stack([euler_parameter_rates(p, axis, frame) for axis in np.eye(3)])
    return block


#: Relative tolerance of :func:`_spinning_bodies`: of a rotor's inertia against its symmetry
#: about the spin axis, of its origin's speed and of the spin of the bodies joined to it.
SPIN_SYMMETRY = 1e-9


def _spinning_bodies(layout: dict[str, Any], state: Any, mass: sp.csc_matrix) -> frozenset[int]:
    """The rigid bodies of `state` that spin about an axis of symmetry through their origin,
    relative to every body joined to them (a rotor in gimbals or bearings; not a disc welded
    to a turning shaft, nor a hub that carries hinged blades round): the origin at rest,
    the inertia in global axes (the mass matrix in dR, dpi) unchanged by a turn about the
    spin axis, and no body joined to it turning at its rate. The motion of such a body's
    mass does not depend on its spin angle, so its small motions in global axes are those
    of time-invariant equations. `mass`: the model's mass matrix M at `state` (coordinates
    x coordinates)."""
    q = np.asarray(state.coordinates, dtype=float)
    qd = np.asarray(state.velocities, dtype=float)
    spins: dict[int, Array] = {}
    for index, b in enumerate(layout["bodies"]):
        if b["kind"] in ("rigid", "flexible") and b["count"] >= 7:
            o = b["offset"]
            spins[index] = angular_velocity(q[o + 3 : o + 7], qd[o + 3 : o + 7])
    joined: dict[int, set[int]] = {}
    markers = layout["markers"]
    for joint in layout["joints"]:
        first, second = (markers[m]["body"] for m in joint["markers"])
        joined.setdefault(first, set()).add(second)
        joined.setdefault(second, set()).add(first)
    candidates = [
        i
        for i, b in enumerate(layout["bodies"])
        if b["kind"] == "rigid" and i in spins and np.linalg.norm(spins[i]) > 0.0
    ]
    found = set()
    for i in candidates:
        o, w = layout["bodies"][i]["offset"], spins[i]
        rate = float(np.linalg.norm(w))
        if np.linalg.norm(qd[o : o + 3]) > SPIN_SYMMETRY * rate * max(
            1.0, np.linalg.norm(q[o : o + 3])
        ):
            continue  # its origin moves: it is carried round
        if any(
            np.linalg.norm(spins.get(j, np.zeros(3)) - w) <= SPIN_SYMMETRY * rate
            for j in joined.get(i, ())
        ):
            continue  # it turns with a body joined to it (welded, or carrying it)
        to_q = _frame_block(q[o + 3 : o + 7], global_axes=True)
        inertia = to_q.T @ mass[o : o + 7, o : o + 7].toarray() @ to_q
        turn = np.zeros((6, 6))
        turn[:3, :3] = turn[3:, 3:] = skew(w / rate)
        if np.linalg.norm(inertia @ turn - turn @ inertia) <= SPIN_SYMMETRY * np.linalg.norm(
            inertia
        ):
            found.add(i)
    return frozenset(found)


def local_partition(
    jacobian: Array, local_elastic: NDArray[np.bool_]
) -> tuple[NDArray[np.int64], Array]:
    """The dependent local coordinates of J = C_q T (:func:`_dependent_columns`) and B_y
    (local coordinates x independent ones): J B_y = 0 with the rows of the independent local
    coordinates the identity."""
    dependent = _dependent_columns(jacobian, local_elastic)
    independent = np.setdiff1d(np.arange(jacobian.shape[1]), dependent)
    local = np.zeros((jacobian.shape[1], len(independent)))
    local[independent] = np.eye(len(independent))
    if len(dependent):
        local[dependent] = -np.linalg.lstsq(
            jacobian[:, dependent], jacobian[:, independent], rcond=None
        )[0]
    return dependent, local


def moving_basis(model: _core.Model, state: Any, mass: sp.csc_matrix) -> tuple[Array, Array, Array]:
    """The basis B (coordinates x independent coordinates) of the motions that keep the
    constraints about `state`, and its first and second time derivatives along the state's
    motion. B = T(q) B_y: T maps the local coordinates of :func:`_frame_transform` (a frame's
    change of origin and small rotation in its own axes, the elastic coordinates) to q, and
    B_y solves J B_y = 0 (J = C_q T) with the rows of the independent local coordinates the
    identity, these chosen by :func:`_dependent_columns` (the elastic ones first).
    Differentiated, J B_y_dot = -J_dot B_y and J B_y_dd = -2 J_dot B_y_dot - J_dd B_y (zero
    rows for the independent coordinates), B_dot = T_dot B_y + T B_y_dot and
    B_dd = T_dd B_y + 2 T_dot B_y_dot + T B_y_dd. The rates of J and T are central
    differences along q(t +- h) = q +- h q_dot + h^2 / 2 q_dd, the step h a turn of
    :data:`BASIS_TURN` rad of the fastest reference coordinate (second order in h: the odd
    terms of the path cancel); they vanish at rest. Dense: (coordinates x independent
    coordinates) each. `mass`: M at `state` (for :func:`_spinning_bodies`)."""
    layout = model.describe()
    time, q = state.time, np.asarray(state.coordinates, dtype=float)
    velocity = np.asarray(state.velocities, dtype=float)
    acceleration = np.asarray(state.accelerations, dtype=float)

    spinning = _spinning_bodies(layout, state, mass)

    def local_jacobian(t: float, at: Array) -> tuple[Array, Array, NDArray[np.bool_]]:
        transform, local_elastic = _frame_transform(layout, at, spinning)
        return _constraint_jacobian(model, t, at) @ transform, transform, local_elastic

    jacobian, transform, local_elastic = local_jacobian(time, q)
    dependent, local = local_partition(jacobian, local_elastic)
    columns = jacobian[:, dependent]

    def solve(right: Array) -> Array:
        return np.linalg.lstsq(columns, right, rcond=None)[0]

    basis = transform @ local
    rate, curvature = np.zeros_like(basis), np.zeros_like(basis)
    elastic = _elastic_mask(layout)
    speed = float(np.max(np.abs(velocity[~elastic]), initial=0.0))
    rise = float(np.max(np.abs(acceleration[~elastic]), initial=0.0))
    if speed == 0.0 and rise == 0.0:
        return basis, rate, curvature  # B of a state at rest does not move
    # h: the step over which the fastest coordinate moves BASIS_TURN, h v + h^2 a / 2 (the
    # root 2 BASIS_TURN / (v + sqrt(v^2 + 2 a BASIS_TURN)), free of the cancellation of
    # (sqrt(v^2 + 2 a BASIS_TURN) - v) / a, which was 0 for a of 1e-30 at 3 m/s).
    h = 2.0 * BASIS_TURN / (speed + np.sqrt(speed**2 + 2.0 * rise * BASIS_TURN))
    ahead = local_jacobian(time + h, q + h * velocity + 0.5 * h * h * acceleration)
    behind = local_jacobian(time - h, q - h * velocity + 0.5 * h * h * acceleration)
    # Differences of J = C_q T and of T (smooth in q), not of the solved B: their round-off
    # is the entries', where B's would carry the solve's over h^2.
    jacobian_rate = (ahead[0] - behind[0]) / (2.0 * h)
    jacobian_curvature = (ahead[0] - 2.0 * jacobian + behind[0]) / (h * h)
    transform_rate = (ahead[1] - behind[1]) / (2.0 * h)
    transform_curvature = (ahead[1] - 2.0 * transform + behind[1]) / (h * h)
    local_rate, local_curvature = np.zeros_like(local), np.zeros_like(local)
    if len(dependent):
        local_rate[dependent] = -solve(jacobian_rate @ local)
        local_curvature[dependent] = -solve(
            2.0 * jacobian_rate @ local_rate + jacobian_curvature @ local
        )
    rate = transform_rate @ local + transform @ local_rate
    curvature = (
        transform_curvature @ local
        + 2.0 * transform_rate @ local_rate
        + transform @ local_curvature
    )
    return basis, rate, curvature


def linearize(
    model: _core.Model | _core.System,
    state: State | str | None = None,
    *,
    inputs: Sequence[PointLoad] = (),
    outputs: Sequence[Any] = (),
    independent: str = "elastic",
) -> LinearizedSystem:
    """Linearizes the equations of motion about `state` (default: :func:`equilibrium` of the
    model; ``"equilibrium"`` and ``"steady-rotation"`` name the states of those functions):
    M, D = dr/dq_dot and K = dr/dq (with the multipliers' constraint Hessians) of the
    augmented system, restricted to the null space of the constraint Jacobian C_q. The
    eigenvalues are those of the motion about a static state, or about a steady rotation
    whose linearized equations do not depend on time (for example the elastic coordinates of
    a body whose reference motion is prescribed); about a state of a trajectory
    (``result.state(k)``) it is the motion at that instant.

    `inputs` (loads, :class:`flexmbd.PointLoad`; `model` must then be a
    :class:`flexmbd.System`) and `outputs` (:class:`flexmbd.NodeDisplacement`,
    :class:`flexmbd.BodyPosition`, :class:`flexmbd.ElasticCoordinate`) make
    :meth:`LinearizedSystem.state_space` the state-space model (A, B, C, D) between them.

    `independent` chooses the coordinates z. ``"elastic"`` (default): z are local coordinates
    (:func:`_frame_transform`: each body frame's change of origin and small rotation in its own
    axes, the elastic coordinates), the elastic ones of the deformable bodies first (generalized
    coordinate partitioning, seed eqs. 27-30, the dependent coordinates pivoted among the
    frames' local coordinates); the dependent coordinates follow the constraints along the
    state's motion, q = q0(t) + B(t) z, and the equations carry the terms of that moving basis
    (:func:`moving_basis`):
    B^T M B z_dd + B^T (D B + 2 M B_dot) z_dot + B^T (K B + D B_dot + M B_dd) z = 0.
    About a steady rotation (a disc welded to a turning shaft, a blade on a free flap hinge
    of a turning hub) these are the time-invariant equations of the rotating frames,
    and the eigenvalues the exact frequencies seen there. ``"null-space"``: an orthonormal basis
    of the null space of C_q at the state, held fixed. With the basis held fixed the welded
    disc's absolute coordinates turn under it, and the frequencies are wrong (a rotor's whirl at
    100 rad/s: 66.1 and 73.1 rad/s instead of 27.0 and 157.9). The two choices agree where B
    does not move (static states, blades whose reference motion is all prescribed), up to
    round-off, which is larger with the null space: its columns mix stiff and soft coordinates
    (the rotor at rest: its first pair of bending frequencies split by 1e-5 against exactly
    equal).

    Raises `InvalidParameterError` for a state of another System, or one whose coordinates
    violate the constraints by more than :data:`STATE_VIOLATION` (naming the joint equation
    violated most), whose velocities violate the velocity constraints or whose accelerations
    and multipliers the equations of motion by more than :data:`MOTION_VIOLATION`
    (:func:`_check_motion`), or with a value that is not finite, and `ArgumentTypeError`
    for inputs or outputs that are not lists of loads and outputs."""
    return _linearize(
        model, state, inputs=inputs, outputs=outputs, independent=independent, consistent=True
    )


def _linearize(
    model: _core.Model | _core.System,
    state: State | str | None,
    *,
    inputs: Sequence[PointLoad],
    outputs: Sequence[Any],
    independent: str,
    consistent: bool,
) -> LinearizedSystem:
    """:func:`linearize`; with `consistent`, the state's velocities must meet the velocity
    constraints and its accelerations and multipliers the equations of motion
    (:func:`_check_motion`), which :func:`linearize_at_rest`'s state with its loads does
    not (nothing balances a free body's loads at rest)."""
    import scipy.linalg as sla

    if independent not in INDEPENDENT:
        raise InvalidParameterError(
            f"independent must be one of {', '.join(INDEPENDENT)}, got {independent!r}",
            item="independent",
        )
    system = model
    model = _model(model)
    if state is None or (isinstance(state, str) and state == "equilibrium"):
        state = equilibrium(model)
    elif isinstance(state, str) and state == "steady-rotation":
        state = steady_rotation(model)
    elif not isinstance(state, State):
        raise InvalidParameterError(
            f"linearize: state must be a flexmbd.State (fm.equilibrium, fm.steady_rotation, "
            f"result.state(k)), 'equilibrium' or 'steady-rotation', got {state!r}",
            item="state",
        )
    if state.accelerations is None or state.multipliers is None:
        raise InvalidParameterError(
            "linearize: the state has no accelerations and multipliers (a state built from "
            "coordinates and velocities, as State.of_model): linearize about fm.equilibrium, "
            "fm.steady_rotation or a result's result.state(k)",
            item="state",
        )
    inputs = _items(inputs, "inputs", (PointLoad,), "flexmbd.PointLoad")
    outputs = _items(
        outputs, "outputs", OUTPUTS, "NodeDisplacement, BodyPosition, ElasticCoordinate"
    )
    _refuse_stray_ids(model, inputs, outputs)
    _check_state(model, state)
    if consistent:
        _check_motion(model, state)
    unheld = unheld_frame_error(model, np.asarray(state.coordinates, dtype=float), state.time)
    if unheld is not None:
        raise unheld  # (its modes were spurious: 12.2 and 132.8 Hz for a beam of 8.18 Hz)
    nq = model.coordinate_count
    args = (
        state.time,
        state.coordinates,
        state.velocities,
        state.accelerations,
        state.multipliers,
    )
    discrete = state.discrete_for(model)  # (None: set from q)
    m = _matrix(model.evaluate(*args, mass=1.0, discrete=discrete))
    d = _matrix(model.evaluate(*args, velocity=1.0, discrete=discrete))
    k = _matrix(model.evaluate(*args, position=1.0, discrete=discrete))
    cq = m[nq:, :nq].toarray()
    if independent == "elastic":
        basis, rate, curvature = moving_basis(model, state, m[:nq, :nq])
    else:
        basis = sla.null_space(cq) if cq.shape[0] else np.eye(nq)
        rate = curvature = np.zeros_like(basis)
    if basis.shape[1] == 0:
        raise InvalidModelError("linearize: the constraints leave no degree of freedom")
    mass, damping, stiffness = (a[:nq, :nq] for a in (m, d, k))
    mass_rate = mass @ rate
    moving_stiffness = basis.T @ (damping @ rate + mass @ curvature)
    moving_damping = 2.0 * basis.T @ mass_rate
    moving = float(np.max(np.abs(moving_stiffness), initial=0.0)) + float(
        np.max(np.abs(moving_damping), initial=0.0)
    )

    linear = LinearizedSystem(
        basis.T @ (mass @ basis),
        basis.T @ (damping @ basis) + moving_damping,
        basis.T @ (stiffness @ basis) + moving_stiffness,
        basis,
        state,
        accuracy=BASIS_ACCURACY * moving,
    )
    layout = model.describe() if inputs or outputs else {}
    if inputs:
        linear.input_forces = input_forces(system, state, inputs)
        linear.input_names = [_label(load, layout) for load in inputs]
    if outputs:
        linear.output_rows = output_rows(model, outputs)
        linear.output_names = [_label(output, layout) for output in outputs]
    return linear


def _label(item: Any, layout: dict[str, Any]) -> str:
    """The label of an input or output, its body or marker named by the model's name for it
    ("position of body arm", not "position of body BodyId(1)")."""
    if item.name is None:
        for field, kind in (("body", "bodies"), ("marker", "markers")):
            index = getattr(getattr(item, field, None), "index", None)
            entries = layout.get(kind) or []
            if isinstance(index, int) and 0 <= index < len(entries) and entries[index].get("name"):
                return dataclasses.replace(item, **{field: entries[index]["name"]}).label()
    return item.label()


#: The outputs :func:`linearize` takes.
OUTPUTS = (NodeDisplacement, BodyPosition, ElasticCoordinate)


def _items(value: Any, name: str, kinds: tuple[type, ...], listed: str) -> list[Any]:
    """The list or tuple `value` of the inputs or outputs `name` of :func:`linearize`, each
    one of `kinds`, else an `ArgumentTypeError` naming the parameter (a single load not in a
    list) or the entry (``outputs[1]``)."""
    if isinstance(value, kinds):
        raise ArgumentTypeError(
            f"linearize: {name} must be a list ({listed}), got a single "
            f"{type(value).__name__}: pass [{type(value).__name__}(...)]",
            item=name,
        )
    if not isinstance(value, list | tuple):
        raise ArgumentTypeError(
            f"linearize: {name} must be a list of {listed}, got {value_text(value)} "
            f"({type(value).__name__})",
            item=name,
        )
    for k, entry in enumerate(value):
        if not isinstance(entry, kinds):
            raise ArgumentTypeError(
                f"linearize: {name}[{k}] must be one of {listed}, got {value_text(entry)} "
                f"({type(entry).__name__})",
                item=f"{name}[{k}]",
            )
    return list(value)


#: Largest violation of the constraints (relative to the largest coordinate, at least 1) of
#: a state that :func:`linearize` takes: a run's states meet them to its Newton tolerance.
STATE_VIOLATION = 1e-6


def _check_state(model: _core.Model, state: State, owner: str = "linearize") -> None:
    """An `InvalidParameterError` for a state that is not one of `model`: of another System
    (its ``system_identity``), of other sizes, or whose coordinates violate the constraints
    by more than :data:`STATE_VIOLATION` (the message names the joint equation violated
    most)."""
    here = identity_of(model)
    if state.system_identity is not None and here is not None and state.system_identity != here:
        raise InvalidParameterError(
            f"{owner}: the state is one of another System (its system_identity differs): "
            "give a state of this system (fm.equilibrium(system), "
            "fm.steady_rotation(system), or result.state(k) of a run of it)",
            item="state",
        )
    nq, nc = model.coordinate_count, model.constraint_count
    sizes = (len(state.coordinates), len(state.multipliers))
    if sizes != (nq, nc):
        raise InvalidParameterError(
            f"{owner}: the state has {sizes[0]} coordinates and {sizes[1]} multipliers, the "
            f"model {nq} and {nc}: it is a state of another model",
            item="state",
        )
    # A NaN of the state reached the core, which reported "the equation of body 'bob' at
    # t = NaN" for a NaN velocity at t = 0.
    if not np.isfinite(state.time):
        raise InvalidParameterError(
            f"{owner}: the state's time must be finite, got {state.time}", item="time"
        )
    for name in ("coordinates", "velocities", "accelerations", "multipliers"):
        values = np.asarray(getattr(state, name), dtype=float)
        expected = nc if name == "multipliers" else nq
        if values.shape != (expected,):
            raise InvalidParameterError(
                f"{owner}: the state's {name} must be {expected} numbers, got shape {values.shape}",
                item=name,
            )
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise InvalidParameterError(
                f"{owner}: the state's {name} must be finite, got {values[bad[0]]} at index "
                f"{bad[0]} (t = {state.time:g})",
                item=name,
            )
    if nc == 0:
        return
    q = np.asarray(state.coordinates, dtype=float)
    zeros = np.zeros(nq)
    violation = np.abs(model.evaluate(state.time, q, zeros, zeros, np.zeros(nc))["residual"][nq:])
    floor = STATE_VIOLATION * max(1.0, float(np.max(np.abs(q), initial=0.0)))
    worst = int(np.argmax(violation))
    if not violation[worst] <= floor:
        joints, names = _row_names(model.describe(), np.array([worst]))
        raise InvalidParameterError(
            f"{owner}: the state's coordinates violate {names} by "
            f"{float(violation[worst]):.3g} at t = {state.time:g} (more than {floor:.3g}): it is "
            "not a configuration of this model (a state of another model, or coordinates "
            "changed by hand)",
            item=joints[0] if joints else "state",
        )


#: Largest violation of the velocity constraints C_q q_dot + C_t = 0 of a state that
#: :func:`linearize` takes, relative to its largest coordinate and velocity (at least 1
#: each), and of its equations of motion, relative to their largest term (the applied and
#: velocity forces, M q_dd + C_q^T lambda, at least |M| max(1, |q_dot|^2)). Far above what a
#: run leaves (generalized-alpha holds the velocity constraints only to its error: 2.6e-6 on
#: the flexible double pendulum at h = 1e-3, 1.8e-4 relative on the overhung rotor's spin
#: driver; at 1e-6 most of their records were refused), far below a state changed by hand
#: (velocities off a joint by 2, multipliers zeroed: a relative residual of 1).
VELOCITY_VIOLATION = 1e-2
MOTION_VIOLATION = 1e-3


def _check_motion(model: _core.Model, state: State) -> None:
    """An `InvalidParameterError` for a state whose velocities violate the velocity
    constraints (naming the joint equation violated most), or whose accelerations and
    multipliers do not satisfy the equations of motion (naming the body and coordinate of
    the largest residual): such a state (edited by hand, its multipliers zeroed) is no state
    of a motion of the model, and its linearization was silently wrong (a pendulum with its
    multipliers zeroed lost its gravity stiffness: eigenvalues 0 for +-3.13i)."""
    nq, nc = model.coordinate_count, model.constraint_count
    q = np.asarray(state.coordinates, dtype=float)
    qd = np.asarray(state.velocities, dtype=float)
    qdd = np.asarray(state.accelerations, dtype=float)
    lam = np.asarray(state.multipliers, dtype=float)
    discrete = state.discrete_for(model)
    zeros_q, zeros_l = np.zeros(nq), np.zeros(nc)
    layout = model.describe()
    ev = model.evaluate(state.time, q, zeros_q, zeros_q, zeros_l, mass=1.0)
    matrix = _matrix(ev)
    if nc:
        rates = matrix[nq:, :nq] @ qd + ev["constraint_rate"]
        scale = max(1.0, float(np.max(np.abs(q), initial=0.0)))
        scale *= max(1.0, float(np.max(np.abs(qd), initial=0.0)))
        worst = int(np.argmax(np.abs(rates)))
        if not abs(rates[worst]) <= VELOCITY_VIOLATION * scale:
            joints, names = _row_names(layout, np.array([worst]))
            raise InvalidParameterError(
                f"linearize: the state's velocities violate the velocity constraint of {names} "
                f"by {abs(float(rates[worst])):.3g} at t = {state.time:g} (C_q q_dot + C_t, more "
                f"than {VELOCITY_VIOLATION * scale:.3g}): they are no velocities of this model's "
                "motion (changed by hand?)",
                item="velocities",
            )
    full = model.evaluate(state.time, q, qd, qdd, lam, discrete=discrete)["residual"][:nq]
    forces = model.evaluate(state.time, q, qd, zeros_q, zeros_l, discrete=discrete)["residual"][:nq]
    # The largest term: the applied and velocity forces, M q_dd + C_q^T lambda, or the size
    # |M| max(1, |q_dot|^2) of an acceleration of 1 (m/s^2, rad/s^2) and of the velocity
    # terms: forces that balance each other leave none of the others (a free rotor spinning
    # on a principal axis at rest lengths, a mass hanging from a spring: residuals of 3e-15
    # were all there was).
    speed = float(np.max(np.abs(qd), initial=0.0))
    scale = max(
        float(np.max(np.abs(forces), initial=0.0)),
        float(np.max(np.abs(full - forces), initial=0.0)),
        float(abs(matrix[:nq, :nq]).max()) * max(1.0, speed**2) if nq else 0.0,
    )
    worst = int(np.argmax(np.abs(full))) if nq else 0
    if nq and not abs(full[worst]) <= MOTION_VIOLATION * scale:
        where = f"coordinate {worst}"
        for body in layout["bodies"]:
            if body["offset"] <= worst < body["offset"] + body["count"]:
                where = f"body '{body['name']}' coordinate {worst - body['offset']}"
        raise InvalidParameterError(
            f"linearize: the state's accelerations and multipliers do not satisfy the equations "
            f"of motion: residual {abs(float(full[worst])):.3g} in {where} at t = "
            f"{state.time:g} (more than {MOTION_VIOLATION:g} of their largest term, "
            f"{scale:.3g}): linearize about fm.equilibrium, fm.steady_rotation or a result's "
            "result.state(k), not a state whose accelerations or multipliers were changed",
            item="accelerations",
        )


#: Largest violation of the constraints at the initial coordinates (relative to the largest
#: coordinate, at least 1) that :func:`linearize_at_rest` takes as assembled.
ASSEMBLED = 1e-8


def _refuse_stray_ids(model: Any, inputs: Sequence[Any], outputs: Sequence[Any]) -> None:
    """Refuses the ids of another System's items in the inputs and outputs (as `Result`,
    `State` and the System's own methods do): a body of another system was taken as this
    one's item of that index, a load on its marker applied to this system's marker."""
    from .system import identity_of, item_name, stray_id, stray_id_error

    identity = identity_of(model)
    if identity is None:
        return
    for item in (*inputs, *outputs):
        fields = [getattr(item, f.name) for f in dataclasses.fields(item)]
        stray = stray_id(identity, fields, lambda it: item_name(identity, it))
        if stray is not None:
            raise stray_id_error(stray, "linearize", item_name(identity, stray))


def _multipliers_at_rest(model: _core.Model, time: float, q: Array, ev: dict[str, Any]) -> Array:
    """The joints' multipliers that carry the loads at rest in configuration `q`: with the
    linear static deflection of the elastic coordinates, [K_af, C_q^T; C_qf, 0] [dq_f;
    lambda] = [-F; 0] in least squares (the reference coordinates held where they are; K_af
    the tangent stiffness's elastic columns). Their geometric stiffness is a hanging
    pendulum's frequency (with zero multipliers it had none, and the upright four-bar's
    +-3.43 were 0). The elastic rows are balanced by the deflection, not by the multipliers:
    in a least-squares balance of every row a weld on an elastic node took the rows' load
    on itself, and a rod hanging with a rigid tip body welded to it swung 18 % slow; and
    where supports are redundant (a beam in two bearings) the deflection shares the load
    between them as the structure does."""
    nq, nc = model.coordinate_count, model.constraint_count
    matrix = _matrix(ev)
    elastic = np.flatnonzero(_elastic_mask(model.describe()))
    cq = matrix[nq:, :nq].toarray()
    count = len(elastic)
    system = np.zeros((nq + nc, count + nc))
    system[:nq, :count] = matrix[:nq, :nq][:, elastic].toarray()
    system[:nq, count:] = cq.T
    system[nq:, :count] = cq[:, elastic]
    rest = ev["residual"][:nq]
    solution = np.linalg.lstsq(system, np.concatenate([-rest, np.zeros(nc)]), rcond=None)[0]
    deflected = q.copy()
    deflected[elastic] += solution[:count]
    zeros = np.zeros(nq)
    for sign in (1.0, -1.0):  # (the residual's sign convention of the multipliers)
        multipliers = sign * solution[count:]
        balanced = model.evaluate(time, deflected, zeros, zeros, multipliers)["residual"][:nq]
        if np.linalg.norm(balanced) <= np.linalg.norm(rest):
            break
    return multipliers


def linearize_at_rest(
    system: _core.System | _core.Model,
    time: float = 0.0,
    *,
    loads: bool = False,
    inputs: Sequence[PointLoad] = (),
    outputs: Sequence[Any] = (),
) -> LinearizedSystem:
    """Linearizes the model about its initial configuration at rest (velocities,
    accelerations and multipliers zero), by default with its applied loads and gravity left
    out (:meth:`flexmbd.System.without_loads`): the free-free modes of a free-flying
    structure (a satellite, a launcher, a part on soft supports), which has no static
    equilibrium for :func:`equilibrium` to find, and whose loads would otherwise bring the
    stiffness of an accelerating state into the modes (a torque fixed to a satellite's bus
    turns with it: a pair of spurious modes near 0.01 Hz). The rigid-body motions come out as
    zero eigenvalues: :meth:`LinearizedSystem.free_motions` counts them and
    :meth:`LinearizedSystem.oscillating` leaves them out. Springs, actuators, drivers and
    callback forces (which may be elastic elements) stay.

    With `loads`, the loads and gravity stay (their stiffness at rest: a follower load's),
    and the joints carry them: the multipliers that balance them at rest (least squares)
    bring their geometric stiffness (a hanging pendulum's frequency); `system` may then be a
    compiled model. `inputs` and `outputs` as in :func:`linearize`.
    Raises `InvalidModelError` naming the joint equation when the initial coordinates violate
    the constraints (the configuration is not assembled: linearize about
    :func:`equilibrium` or a result's ``result.state(k)`` instead)."""
    from .system import System

    time = number(time, "time")
    if not isinstance(system, _core.System | _core.Model):
        raise not_a_model(system, "system")
    if not loads:
        if not isinstance(system, System):
            raise InvalidParameterError(
                "linearize_at_rest: leaving the loads out needs the flexmbd.System (a compiled "
                "model's loads cannot be removed); pass loads=True to keep them",
                item="system",
            )
        system = system.without_loads()
    model = _model(system)
    nq, nc = model.coordinate_count, model.constraint_count
    q = np.array(model.initial_coordinates, dtype=float)
    zeros = np.zeros(nq)
    ev = model.evaluate(time, q, zeros, zeros, np.zeros(nc), position=1.0)
    violation = np.abs(ev["residual"][nq:])
    floor = ASSEMBLED * max(1.0, float(np.max(np.abs(q), initial=0.0)))
    if np.any(violation > floor):
        layout = model.describe()
        worst = np.argsort(-violation)[: min(3, int(np.sum(violation > floor)))]
        joints, names = _row_names(layout, worst)
        raise InvalidModelError(
            f"linearize_at_rest: the initial coordinates violate {names} by up to "
            f"{float(violation[worst[0]]):.3g}: the configuration is not assembled (linearize "
            "about fm.equilibrium or a result's result.state(k))",
            item=joints[0] if joints else None,
        )
    multipliers = np.zeros(nc)
    if loads and nc:
        multipliers = _multipliers_at_rest(model, time, q, ev)
    state = State(
        time,
        q,
        zeros,
        zeros,
        multipliers,
        layout=model.describe(),
        flexible=model.flexible_bodies,
        system_identity=identity_of(model),
    )
    return _linearize(
        system, state, inputs=inputs, outputs=outputs, independent="elastic", consistent=False
    )
