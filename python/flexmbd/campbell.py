"""Campbell diagrams: the frequencies of a rotor's modes against its speed.

    diagram = fm.campbell(system, driver="hub", speeds=np.linspace(0, 120, 25), modes=6)
    diagram.critical_speeds(orders=(1, 2))          # where k x speed meets a mode
    fm.plot_campbell(diagram, "campbell.png")
    diagram.to_xarray()                             # speed x mode

At each speed the angle driver `driver` turns at that constant speed (the system is built
again with it, :meth:`flexmbd.System.with_driver`); :func:`flexmbd.steady_rotation` finds the
centrifugally stretched state and :func:`flexmbd.linearize` the motion about it (spin
softening, the geometric stiffness of the stretched state, Coriolis and gyroscopic terms in
the damping matrix). The damped complex eigenvalues give the frequencies and damping ratios.
Modes are followed from one speed to the next by the modal assurance criterion of their
shapes (MAC = |a^H b|^2 / (|a|^2 |b|^2), an assignment that maximizes the total), not by
sorting: a curve keeps its mode through a crossing with another. The linearization takes the
elastic coordinates as the independent ones (``linearize(..., independent="elastic")``): about
a steady rotation they are the coordinates of the rotating frames, also for bodies joined to
the turning ones (a disc welded to a shaft), and the frequencies are exact in those frames.

Whirl. Each mode's whirl is measured on the nodes of the deformable bodies that the driver
turns, in their frames: with a and b the complex amplitudes of a node's motion (its
translation, and its small rotation times the body's size) along two axes e1, e2 normal to
the spin axis n (e1 x e2 = n, n the body's angular velocity per unit driver speed), and c
along n, the whirl ratio r = 2 Im(sum a conj(b)) / sum(|a|^2 + |b|^2 + |c|^2) is +1 for a
circular whirl in the spin sense, -1 against it, near 0 for planar, axial and torsional
motion. In the rotating frame a mode of frequency w_r with |r| >= :data:`WHIRL_THRESHOLD`
turns at sign(r) w_r about n; a frame turning at the speed W about n adds W: in the fixed
frame it whirls at sign(r) w_r + W, forward (in the spin sense) where that has the sign of W,
backward otherwise (reference R8 checks this: forward whirl w_f appears in the rotating frame
at w_f - W, backward whirl w_b at -(w_b + W)). This holds for an axisymmetric rotor, whose
modes in the rotating frame are circular; modes that do not whirl (|r| below the threshold:
axial, torsional) are reported at their rotating-frame frequency, which is theirs in both
frames when the rotor is axisymmetric (a planar mode of a blade has no single fixed-frame
frequency). Where two modes have the same frequency (every whirl pair at W = 0) the pair is
resolved into its circular combinations, so that forward and backward are followed from rest.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._checks import integer, number, numbers_array
from .errors import ArgumentTypeError, InvalidParameterError
from .progress import track as track_progress
from .rotation import angular_velocity

Array = NDArray[np.float64]

#: Smallest MAC of a mode's shape with the one it had at the previous speed for the candidate
#: to continue it; below it the mode has no continuation there (a gap of NaN, as where it
#: stops oscillating).
FOLLOW_MAC = 0.5

#: Candidate modes per speed beyond those followed (a followed mode may rise above the others).
EXTRA_CANDIDATES = 6

#: Frames of the reported frequencies.
FRAMES = ("rotating", "fixed")

#: Smallest |whirl ratio| of a whirling mode: its circular component in the whirl's sense is
#: then at least sqrt(3) times the other.
WHIRL_THRESHOLD = 0.5

#: Relative difference of frequencies below which two modes are one degenerate pair.
DEGENERATE = 1e-8

#: Whirl labels.
FORWARD, BACKWARD = "forward", "backward"


@dataclass
class CampbellDiagram:
    """The modes of a rotor against its speed: `speeds` (rad/s), and per speed and followed
    mode the damped `frequencies` (Hz, in the `frame` "rotating" or "fixed"), `damping`
    ratios and complex `shapes` (in the coordinates q of the model, rotating frame), and the
    MAC with which each mode was matched to the speed before (`mac`, 1 at the first speed).
    Where a followed mode does not oscillate (its eigenvalues real: diverged, or overdamped)
    its frequency, damping, MAC, whirl ratio and shape are NaN and its whirl None: a gap,
    as plots draw it.
    `whirl` holds the whirl of each mode in the fixed frame, "forward", "backward" or None
    (a mode that does not whirl), `whirl_ratio` its signed circularity in the fixed frame
    (+1 circular forward, -1 circular backward; see the module)."""

    speeds: Array
    frequencies: Array
    damping: Array
    shapes: NDArray[np.complex128] = field(repr=False)
    mac: Array = field(repr=False)
    driver: str = ""
    frame: str = "rotating"
    whirl: NDArray[np.object_] | None = field(default=None, repr=False)
    whirl_ratio: Array | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.whirl is None:
            self.whirl = np.full(self.frequencies.shape, None, dtype=object)
        if self.whirl_ratio is None:
            self.whirl_ratio = np.zeros(self.frequencies.shape)

    @property
    def mode_count(self) -> int:
        return self.frequencies.shape[1]

    @property
    def whirl_labels(self) -> list[str | None]:
        """Per followed mode its whirl ("forward", "backward"), if the same at every speed;
        None for a mode that does not whirl at some speed or changes its direction."""
        labels: list[str | None] = []
        for m in range(self.mode_count):
            oscillating = np.isfinite(self.frequencies[:, m])
            seen = set(self.whirl[oscillating, m])  # type: ignore[index]
            labels.append(seen.pop() if len(seen) == 1 else None)
        return labels

    def critical_speeds(self, orders: Any = (1, 2, 3)) -> list[dict[str, float]]:
        """Where an excitation order meets a mode: the speeds W (rad/s) at which a mode's
        frequency f(W) equals k W / (2 pi) for the orders k, interpolated linearly between
        the speeds computed; a list of dicts with order, mode, speed, frequency (Hz) and the
        mode's whirl label, by speed. In the fixed frame, order 1 meeting a forward whirl is
        the critical speed of the rotor's unbalance."""
        found = []
        w = self.speeds
        for k in _orders(orders):
            line = k * w / (2 * np.pi)
            for m in range(self.mode_count):
                gap = self.frequencies[:, m] - line
                for i in np.flatnonzero(np.sign(gap[:-1]) * np.sign(gap[1:]) < 0):
                    t = gap[i] / (gap[i] - gap[i + 1])
                    speed = w[i] + t * (w[i + 1] - w[i])
                    found.append(
                        {
                            "order": float(k),
                            "mode": m,
                            "speed": float(speed),
                            "frequency": float(k * speed / (2 * np.pi)),
                            "whirl": self.whirl_labels[m],
                        }
                    )
        return sorted(found, key=lambda c: c["speed"])

    def to_xarray(self) -> Any:
        """The diagram as an xarray Dataset over speed (rad/s) and mode: frequency (Hz, in
        the frame of the attribute ``frame``), damping ratio, MAC, whirl ratio and the whirl
        ("forward", "backward" or "" for a mode that does not whirl); the coordinate
        ``whirl_label`` on mode holds :attr:`whirl_labels` ("" for None)."""
        import xarray as xr

        def text(labels: Any) -> NDArray[np.str_]:
            return np.vectorize(lambda v: v or "", otypes=[str])(np.asarray(labels, dtype=object))

        coords = {
            "speed": self.speeds,
            "mode": np.arange(self.mode_count),
            "whirl_label": ("mode", text(self.whirl_labels)),
        }
        data = xr.Dataset(
            {
                "frequency": (("speed", "mode"), self.frequencies),
                "damping_ratio": (("speed", "mode"), self.damping),
                "mac": (("speed", "mode"), self.mac),
                "whirl_ratio": (("speed", "mode"), self.whirl_ratio),
                "whirl": (("speed", "mode"), text(self.whirl)),
            },
            coords=coords,
        )
        data["frequency"].attrs["units"] = "Hz"
        data["speed"].attrs["units"] = "rad/s"
        data.attrs["driver"] = self.driver
        data.attrs["frame"] = self.frame
        return data


def _mac(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> Array:
    """MAC of every column of `a` with every column of `b`, and with its conjugate (the
    larger): a mode whose rotating-frame frequency passes through zero (a forward whirl at
    its critical speed) continues as the conjugate of its shape, the representative of the
    eigenvalue of positive imaginary part."""
    cross = np.maximum(np.abs(a.conj().T @ b), np.abs(a.T @ b)) ** 2
    norms = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    return cross / np.where(norms > 0.0, norms, 1.0)


@dataclass
class _WhirlProbe:
    """Rows that take a shape in q (columns: modes) to the amplitudes a, b (along e1, e2
    normal to the spin axis) and c (along it) of the nodes of the turning deformable bodies
    (see the module): sparse (node amplitudes x coordinates) each."""

    along_e1: Any
    along_e2: Any
    along_axis: Any

    def amplitudes(self, shapes: NDArray[np.complex128]) -> tuple[Any, Any, Any]:
        return self.along_e1 @ shapes, self.along_e2 @ shapes, self.along_axis @ shapes

    def ratios(self, shapes: NDArray[np.complex128]) -> Array:
        """The whirl ratio of each column of `shapes` in the rotating frame about the axis."""
        a, b, c = self.amplitudes(shapes)
        turn = 2.0 * np.sum(np.imag(a * b.conj()), axis=0)
        size = np.sum(np.abs(a) ** 2 + np.abs(b) ** 2 + np.abs(c) ** 2, axis=0)
        return np.divide(turn, size, out=np.zeros_like(turn), where=size > 0.0)

    def circular(self, shapes: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """The combinations of the columns of `shapes` (modes of one frequency) that whirl
        most purely: the eigenvectors of the whirl form i (A^H B - B^H A) relative to the
        size form A^H A + B^H B + C^H C; the columns unchanged when none whirls."""
        import scipy.linalg as sla

        a, b, c = self.amplitudes(shapes)
        turn = 1j * (a.conj().T @ b - b.conj().T @ a)
        size = a.conj().T @ a + b.conj().T @ b + c.conj().T @ c
        try:
            ratios, combination = sla.eigh(turn, size)
        except (sla.LinAlgError, ValueError):
            return shapes  # a mode without motion of the turning bodies' nodes
        if np.max(np.abs(ratios)) < WHIRL_THRESHOLD:
            return shapes
        return np.asarray(shapes @ combination)


def _body_size(nodes: Array) -> float:
    """The largest distance of a body's nodes from their centre (m), at least 1e-12."""
    centre = nodes.mean(axis=0)
    return max(float(np.max(np.linalg.norm(nodes - centre, axis=1))), 1e-12)


def _whirl_probe(system: Any, driver: str, time: float) -> _WhirlProbe | None:
    """The whirl rows of the deformable bodies that `driver` turns (their angular velocity
    per unit speed of the driver, at the model's initial coordinates, is not zero); None when
    it turns none."""
    import scipy.sparse as sp

    from ._boundary import Polynomial
    from .analysis import _elastic_mask, _prescribed_rates
    from .system import elastic_basis

    start = float(system.driver_function(driver)(time))
    unit = system.with_driver(driver, Polynomial([start - time, 1.0])).compile()
    layout = unit.describe()
    q = np.asarray(unit.initial_coordinates, dtype=float)
    velocity, _ = _prescribed_rates(unit, time, q, ~_elastic_mask(layout))
    nq = unit.coordinate_count
    rows: list[list[Any]] = [[], [], []]
    for index, data in unit.flexible_bodies.items():
        entry = layout["bodies"][index]
        parameters = slice(entry["offset"] + 3, entry["offset"] + 7)
        spin = angular_velocity(q[parameters], velocity[parameters], frame="body")
        rate = float(np.linalg.norm(spin))
        if rate < 1e-9:
            continue
        axis = spin / rate
        # e1: the body axis least along the spin axis, made normal to it.
        first = np.eye(3)[int(np.argmin(np.abs(axis)))]
        first = first - axis * (first @ axis)
        first /= np.linalg.norm(first)
        directions = (first, np.cross(axis, first), axis)
        basis = elastic_basis(data).tocsr()
        d = data.dofs_per_node
        parts = [(0, 1.0)] + ([(3, _body_size(np.asarray(data.nodes)))] if d >= 6 else [])
        columns = np.arange(entry["offset"] + 7, entry["offset"] + entry["count"])
        place = sp.csr_matrix(
            (np.ones(len(columns)), (np.arange(len(columns)), columns)),
            shape=(len(columns), nq),
        )
        for k, direction in enumerate(directions):
            for first_row, length in parts:
                picked = sum(
                    direction[j] * basis[first_row + j :: d] for j in range(3) if direction[j]
                )
                rows[k].append(length * sp.csr_matrix(picked) @ place)
    if not rows[0]:
        return None
    return _WhirlProbe(*(sp.vstack(r).tocsr() for r in rows))


def _resolve_pairs(
    frequencies: Array, shapes: NDArray[np.complex128], probe: _WhirlProbe | None
) -> NDArray[np.complex128]:
    """`shapes` with every group of modes of one frequency (relative difference below
    :data:`DEGENERATE`) replaced by its circular combinations (:meth:`_WhirlProbe.circular`)."""
    if probe is None or len(frequencies) < 2:
        return shapes
    shapes = shapes.copy()
    k = 0
    while k < len(frequencies):
        end = k + 1
        while end < len(frequencies) and frequencies[end] - frequencies[k] <= DEGENERATE * max(
            abs(frequencies[k]), 1e-300
        ):
            end += 1
        if end - k > 1:
            shapes[:, k:end] = probe.circular(shapes[:, k:end])
        k = end
    return shapes


def _fixed_frame(
    frequencies: Array, ratios: Array, speed: float
) -> tuple[Array, NDArray[np.object_], Array]:
    """Fixed-frame frequencies (Hz), whirl labels and signed whirl ratios of modes of the
    rotating frame with `frequencies` (Hz) and whirl `ratios` about the spin axis at `speed`
    (rad/s; see the module)."""
    sense = 1.0 if speed >= 0.0 else -1.0
    whirling = np.abs(ratios) >= WHIRL_THRESHOLD
    signed = np.sign(ratios) * frequencies + speed / (2.0 * np.pi)
    fixed = np.where(whirling, np.abs(signed), frequencies)
    forward = signed * sense > 0.0
    labels = np.full(len(frequencies), None, dtype=object)
    labels[whirling & forward] = FORWARD
    labels[whirling & ~forward] = BACKWARD
    direction = np.where(whirling, np.where(forward, 1.0, -1.0), np.sign(ratios) * sense)
    return fixed, labels, direction * np.abs(ratios)


def _angle_driver(system: Any, driver: str) -> None:
    """InvalidParameterError unless `driver` names an angle driver of `system` (a translation
    driver does not turn a rotor); UnknownItemError when no driver has that name."""
    system.driver_function(driver)  # UnknownItemError naming it
    for method, _, kwargs in system.building_calls:
        if kwargs.get("name") == driver and method == "add_translation_driver":
            raise InvalidParameterError(
                f"campbell: driver {driver!r} is a translation driver; a Campbell diagram "
                "needs an angle driver (a rotation) to turn the rotor",
                item=f"driver '{driver}'",
            )


def _drivers_met_at(system: Any, time: float) -> Array:
    """The model's initial coordinates with the parts the drivers move turned to their
    values at `time` (`analysis._turned_to_drivers`, on the model as built: the speeds'
    drivers are made to have its angle at `time`), from which :func:`campbell` starts every
    speed; InvalidParameterError naming `time` when they still do not meet the drivers
    there (the equilibrium's own error advised "pass coordinates=", which campbell does not
    take)."""
    from .analysis import _check_drivers_at_start, _turned_to_drivers
    from .errors import InvalidModelError

    model = system.compile()
    layout = model.describe()
    q = _turned_to_drivers(model, time, np.asarray(model.initial_coordinates, float), layout)
    try:
        _check_drivers_at_start(model, time, q, layout)
    except InvalidModelError as error:
        raise InvalidParameterError(
            f"campbell at time = {time:g}: the model's initial coordinates violate "
            f"{error.item or 'a driver'} there (its motion has moved on since the initial "
            "configuration); campbell starts every speed from the initial coordinates: use a "
            "time at which they meet the drivers (time=0 for a model built at its drivers' "
            "start), or build the system turned to the drivers' angles at that time",
            item="time",
        ) from None
    return q


#: The speed, relative to the fastest of a diagram, at which :func:`campbell` takes the modes
#: of a rotor at rest that has free motions there (their limit at W -> 0).
ZERO_SPEED = 1e-6


def campbell(
    system: Any,
    driver: str,
    speeds: Any,
    *,
    modes: int = 6,
    time: float = 0.0,
    gyroscopic: bool = True,
    frame: str = "rotating",
    progress: bool | Callable[[int, int], object] | None = None,
) -> CampbellDiagram:
    """The Campbell diagram of `system` (a :class:`flexmbd.System`) turned by its angle
    driver `driver` at each of `speeds` (rad/s, ascending): the `modes` lowest oscillating
    modes at the first speed, followed across the speeds by their shapes (see the module).
    At each speed the driver's angle is theta(time) + W (t - time), the state the steady
    rotation at `time`. `gyroscopic=False` leaves the velocity-dependent terms (Coriolis
    coupling, gyroscopic moments, damping) out of the eigenvalue problem. `frame` is that of
    the reported frequencies: "rotating" (the frames that turn with the rotor, where a blade's
    modes are seen) or "fixed" (the ground, where a rotor's whirl is seen: forward whirl at
    w_rotating + W, backward at w_rotating - W; needs a deformable body turned by the
    driver). Every mode gets its whirl label ("forward", "backward" or None) either way.
    `progress`: True shows a progress bar of the speeds, a function is called as
    ``progress(done, total)`` (:func:`flexmbd.progress.track`).

    Raises `UnknownItemError` for an unknown driver, `InvalidParameterError` for a driver that
    is not an angle driver, an unknown frame, speeds not ascending, and "fixed" for a model
    whose driver turns no deformable body."""
    from .analysis import _steady_rotation, equilibrium, linearize, not_a_model
    from .system import System

    if not isinstance(system, System):
        if not isinstance(system, _core.Model):
            raise not_a_model(system, "system", "a flexmbd.System")
        raise InvalidParameterError(
            "campbell needs a flexmbd.System (it builds the system again at every speed)",
            item="system",
        )
    if frame not in FRAMES:
        raise InvalidParameterError(
            f"frame must be one of {', '.join(FRAMES)}, got {frame!r}", item="frame"
        )
    if not isinstance(gyroscopic, bool | np.bool_):  # ("no" was True)
        raise ArgumentTypeError(
            f"gyroscopic must be True or False, got {gyroscopic!r}", item="gyroscopic"
        )
    time = number(time, "time")  # (a NaN reached a Polynomial, whose error named it)
    speeds = numbers_array(speeds, "speeds")
    if speeds.ndim > 1:  # (a 2-D array was flattened)
        raise InvalidParameterError(
            f"speeds must be one list of speeds, got an array of shape {speeds.shape}",
            item="speeds",
        )
    speeds = speeds.ravel()
    count = integer(modes, "modes")
    if count < 1:
        raise InvalidParameterError(f"modes must be at least 1, got {count}", item="modes")
    if not np.all(np.isfinite(speeds)):
        raise InvalidParameterError("speeds must be finite", item="speeds")
    if len(speeds) == 0 or np.any(np.diff(speeds) <= 0):
        raise InvalidParameterError("speeds must be ascending and not empty", item="speeds")
    _angle_driver(system, driver)
    start_coordinates = _drivers_met_at(system, time)
    start = float(system.driver_function(driver)(time))
    probe = _whirl_probe(system, driver, time)
    if frame == "fixed" and probe is None:
        raise InvalidParameterError(
            f"campbell: driver {driver!r} turns no deformable body, so the whirl of the "
            "modes, and their frequencies in the fixed frame, are not defined",
            item="frame",
        )
    from ._boundary import Polynomial

    frequencies, damping, shapes, mac, whirl, ratios = [], [], [], [], [], []
    followed = None

    def modes_at(w: float) -> tuple[Array, Array, Array]:
        turning = system.with_driver(driver, Polynomial([start - w * time, float(w)]))
        model = turning.compile()
        # (the state's stability is not asked for: its linearization is the one below)
        state = (
            _steady_rotation(model, time, {"coordinates": start_coordinates}, stability=False)
            if w
            else equilibrium(model, time, coordinates=start_coordinates)
        )
        linear = linearize(model, state, independent="elastic")
        if not gyroscopic:
            linear = linear.without_velocity_terms()
        return linear.oscillating(relative_floor=0.0)

    fastest = float(np.max(np.abs(speeds), initial=0.0))
    for w in track_progress(speeds, progress, "campbell diagram", unit="speeds"):
        f, zeta, phi = modes_at(w)
        if w == 0.0 and len(f) < count + EXTRA_CANDIDATES and fastest > 0.0:
            # At rest a mode that the spin stiffens may be a free motion (a blade on a free
            # lag hinge: no oscillation, "0 oscillating modes at 0 rad/s"): the diagram's
            # limit at W -> 0, a turn of ZERO_SPEED of the fastest speed, gives it (its
            # frequency ~ W).
            slow = modes_at(ZERO_SPEED * fastest)
            if len(slow[0]) > len(f):
                f, zeta, phi = slow
        # Candidates: the modes of the lowest |s| (the undamped frequency), not of the lowest
        # damped frequency, which heavily damped stiff modes would crowd.
        natural = f / np.sqrt(np.clip(1.0 - zeta**2, 1e-300, None))
        nearest = np.argsort(natural, kind="stable")[: count + EXTRA_CANDIDATES]
        f, zeta, phi = f[nearest], zeta[nearest], phi[:, nearest]
        phi = _resolve_pairs(f, phi, probe)
        # found: the followed modes that have a candidate at this speed; the others no
        # longer oscillate here (diverged: real eigenvalues), NaN in the diagram.
        found = np.ones(count, dtype=bool)
        pick = np.arange(count)
        if followed is None:
            if len(f) < count:
                raise InvalidParameterError(
                    f"campbell: the model has {len(f)} oscillating modes at {w:g} rad/s, "
                    f"{count} asked for",
                    item="modes",
                )
            match = np.ones(count)
            followed = phi[:, pick].copy()
        else:
            from scipy.optimize import linear_sum_assignment

            table = _mac(followed, phi)
            if probe is not None:
                # A forward whirl and the backward whirl of the same frequency (at rest) have
                # conjugate shapes: a mode keeps its whirl.
                _, candidates, _ = _fixed_frame(f, probe.ratios(phi), float(w))
                kept = [[a is None or b is None or a == b for b in candidates] for a in whirl[-1]]
                table = np.where(np.array(kept, dtype=bool).reshape(table.shape), table, 0.0)
            # Fewer candidates than followed modes (a table of no columns raised a plain
            # ValueError): the modes left without one are the gaps.
            rows, columns = linear_sum_assignment(-table) if table.size else ([], [])
            # A candidate unlike the mode is no continuation of it: the mode stopped
            # oscillating and the assignment took an unrelated one (an asymmetric shaft's
            # first mode between its two critical speeds took a 51 Hz mode at MAC 0.33 and
            # followed it from there, never to return).
            strong = table[rows, columns] >= FOLLOW_MAC if table.size else np.zeros(0, bool)
            rows = np.asarray(rows, dtype=np.int64)[strong]
            columns = np.asarray(columns, dtype=np.int64)[strong]
            found[:] = False
            found[rows] = True
            pick[rows] = columns
            match = np.full(count, np.nan)
            match[rows] = table[rows, columns]
            # A mode without a candidate keeps its last shape, to be found again by it.
            followed[:, found] = phi[:, pick[found]]
        rotating = np.full(count, np.nan)
        rotating[found] = f[pick[found]]
        current = np.where(found[None, :], followed, np.nan)
        if probe is None:
            fixed, labels, signed = rotating, np.full(count, None, dtype=object), np.zeros(count)
        else:
            fixed, labels, signed = _fixed_frame(rotating, probe.ratios(followed), float(w))
            labels[~found] = None
            signed[~found] = np.nan
        damped = np.full(count, np.nan)
        damped[found] = zeta[pick[found]]
        zeta = damped
        if frame == "fixed":
            # The decay rate -Re s is that of both frames; the ratio is to |s| of the frame.
            decay = 2 * np.pi * rotating * zeta / np.sqrt(np.clip(1.0 - zeta**2, 1e-300, None))
            size = np.hypot(decay, 2 * np.pi * fixed)
            zeta = np.divide(decay, size, out=np.zeros_like(decay), where=size > 0.0)
        frequencies.append(fixed if frame == "fixed" else rotating)
        whirl.append(labels)
        ratios.append(signed)
        damping.append(zeta)
        shapes.append(current)
        mac.append(match)
    return CampbellDiagram(
        speeds=speeds,
        frequencies=np.array(frequencies),
        damping=np.array(damping),
        shapes=np.array(shapes),
        mac=np.array(mac),
        driver=driver,
        frame=frame,
        whirl=np.array(whirl, dtype=object),
        whirl_ratio=np.array(ratios),
    )


def _orders(orders: Any) -> Array:
    """The excitation orders k of the lines k W: finite numbers (one, or a sequence), else an
    `InvalidParameterError` naming `orders`."""
    values = np.atleast_1d(numbers_array(orders, "orders")).ravel()
    bad = np.flatnonzero(~np.isfinite(values))
    if len(bad):
        raise InvalidParameterError(
            f"orders must be finite, got {values[bad[0]]} at index {bad[0]}", item="orders"
        )
    return values


def plot_campbell(
    diagram: CampbellDiagram,
    path: str | os.PathLike[str] | None = None,
    *,
    orders: Any = (1, 2, 3),
    ax: Any = None,
) -> Any:
    """Draws the Campbell diagram: each followed mode's frequency (Hz) against the speed
    (rad/s), forward whirl solid, backward whirl dashed, modes that do not whirl dotted; the
    excitation-order lines k W / (2 pi) and their crossings with the modes (critical speeds,
    circled). Saves to `path` if given; returns the Axes (without `ax`, of a new figure that
    pyplot does not manage, as :mod:`flexmbd.plotting`'s: the backend is left as it is, and
    no figure stays open in pyplot; it switched the backend to Agg and kept every figure)."""
    from matplotlib.figure import Figure

    if ax is None:
        ax = Figure(figsize=(7, 5)).subplots()
    w = diagram.speeds
    styles = {FORWARD: "-", BACKWARD: "--", None: ":"}
    whirling = any(label is not None for label in diagram.whirl.ravel())  # type: ignore[union-attr]
    for m, label in enumerate(diagram.whirl_labels):
        name = f"mode {m + 1}" + (f", {label or 'no'} whirl" if whirling else "")
        style = styles[label] if whirling else "-"
        ax.plot(w, diagram.frequencies[:, m], style, lw=1.5, label=name)
    top = float(np.nanmax(diagram.frequencies, initial=0.0)) * 1.05 or 1.0
    for k in _orders(orders):
        ax.plot(w, k * w / (2 * np.pi), "k--", lw=0.8)
        ax.annotate(f"{k:g}x", (w[-1], min(k * w[-1] / (2 * np.pi), top)), fontsize=8)
    for c in diagram.critical_speeds(orders):
        ax.plot(c["speed"], c["frequency"], "o", mfc="none", mec="r", ms=8)
    ax.set_ylim(0.0, top)
    ax.set_xlabel("speed (rad/s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(f"Campbell diagram (driver {diagram.driver!r}, {diagram.frame} frame)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    if path is not None:
        ax.figure.tight_layout()
        ax.figure.savefig(path)
    return ax
