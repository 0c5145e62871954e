"""Floquet analysis: the stability of a periodic motion.

About a static state or a steady rotation the linearized equations do not depend on time and
their eigenvalues decide stability (:func:`flexmbd.linearize`). About a periodic motion (a
pendulum on a vibrating support, a blade whose hub is pitched every turn, an anisotropic
rotor seen from the ground) they are periodic, and the eigenvalues at one instant ("frozen
time") decide nothing: a pendulum hanging on a support shaken at twice its frequency is
stable at every instant and grows. Floquet's theory decides instead: a small motion z(t)
about the periodic one returns after a period as z(T) = Phi z(0), and the motion is stable
where every eigenvalue mu of the monodromy matrix Phi (the Floquet multipliers) has
|mu| <= 1. The characteristic exponents log(mu) / T are the eigenvalues' counterparts
(their imaginary parts known up to multiples of 2 pi / T).

:func:`floquet` builds Phi from runs of the model itself (:func:`flexmbd.simulate`): each
column from two runs of one period started at small displacements (and velocities) +-eps
along an independent coordinate, central differences of the end states. The coordinates z
are those of :func:`flexmbd.linearize` with ``independent="elastic"``: a frame's change of
origin and small rotation in its own axes and the elastic coordinates, the dependent ones
(generalized coordinate partitioning) solved from the constraints, so that every run starts
on the constraints with the other independent coordinates and velocities unchanged. 2 n
independent coordinates take 4 n runs of a period.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._checks import number
from .errors import ArgumentTypeError, InvalidParameterError, NewtonDivergedError, NonFiniteError
from .progress import track as track_progress
from .rotation import angular_velocity, euler_parameters_to_matrix
from .state import State

Array = NDArray[np.float64]

#: Multipliers within this distance of the unit circle are neutral (a conservative motion's
#: are all on it): :attr:`FloquetAnalysis.stable` is True while none lies further out. Above
#: the differences' own error: 1e-11 on rigid models, 4e-8 on the flexible double pendulum
#: (whose beams' geometric stiffness is cubic in their deflection).
NEUTRAL = 1e-5
#: ... or, when larger, within the start state's change over the period (its periodicity):
#: the runs' error, which shows there, shows in |mu| too (the overhung rotor of the examples
#: at 100 rad/s, stable: |mu| - 1 = 0.45 times the periodicity at 200, 400, 800 and 1600
#: steps a turn, 7.4e-5 at 400; as growing motions they made a stable rotor "unstable").

#: Real multipliers within this distance of 1 whose eigenvectors are within
#: :data:`DRIFT_COSINE` of parallel (|cos| at least) are a split double 1, a drift
#: (:attr:`FloquetAnalysis.drifts`): measured 1.8e-3 (a wheel spinning freely at 100 rad/s,
#: cosine 0.998), 1.3e-3 (at 0.03 rad/s, a period of 209 s: cosine 1.0), 1e-3 (a free body
#: spinning about its major axis at 0.05 rad/s), 3e-4 (a pendulum swinging at 2 rad).
DRIFT_SPREAD = 1e-2
DRIFT_COSINE = 0.99

#: Largest change of a start state over one period (in its coordinates and rates, local as
#: z, relative to max(1, their size)) that :func:`floquet` takes as periodic. The
#: runs' own errors show in it (a slider on a turntable at 15 rad/s, one turn in 400 steps of
#: generalized-alpha: its spin came back 1.0e-5 off, the error of the integration of its
#: rotation exciting its torsion spring); a wrong period or a state off the periodic motion
#: changes by far more.
PERIODICITY = 1e-3

#: Spectral radius of the default solver. At 1 (the trapezoidal rule, whose velocities
#: generalized-alpha projects after every step) the projection put 1.2e-2 into |mu| of an
#: axial mode the steps do not resolve (|s| h = 3.1) of the flexible double pendulum at rest
#: (without it 1.5e-6); at 0.99 the largest |mu| - 1 is 1.9e-7, and the damping of the
#: resolved modes is below the differences' error.
SPECTRAL_RADIUS = 0.99

#: Spectral radius of the default solver when a run at :data:`SPECTRAL_RADIUS` failed: the
#: modes the steps do not resolve are then hardly damped, and a blade with geometric
#: stiffness (its axial and bending motions coupled) was driven unstable by an axial one
#: perturbed by 1e-6 m (a 4-element blade at 20 rad/s, 400 steps a turn: Newton diverged);
#: at 0.95 and below it ran, the resolved modes' multipliers the same to 2e-4.
FALLBACK_SPECTRAL_RADIUS = 0.9

#: The default solver damps the modes its steps do not resolve within the period: a run
#: started off the periodic motion sets them moving (in generalized-alpha's first steps by
#: about |s| h times the perturbation), and at spectral radius rho they decay as rho^N over
#: the N steps of the period. Where the stiffest mode of the linearization at the start,
#: |s| h times 0.99^N, is above :data:`UNRESOLVED_LIMIT`, the spectral radius is lowered to
#: (:data:`UNRESOLVED_DECAY` / (|s| h))^(1 / N): the overhung rotor of the examples at 100
#: rad/s, 400 steps a turn, has modes up to |s| h = 7231, whose start put multipliers of up
#: to 75 (11 "growing" motions) into the analysis of a stable rotor at 0.99 (2.3 left at
#: 0.98: |mu| 11; 0.036 at 0.97: none); the flexible double pendulum's axial mode (|s| h =
#: 3.1, 0.056 at 0.99) cost 1.9e-7.
UNRESOLVED_LIMIT = 1.0
UNRESOLVED_DECAY = 1e-4

#: Newton iterations that put a perturbed start back on the constraints, and the residual
#: (relative to max(1, |q|)) accepted where they stall at round-off.
PROJECTION_ITERATIONS = 50
PROJECTED = 1e-12

#: Newton's tolerance of the default solver: the difference quotients divide the runs'
#: errors by the perturbation, so the runs must be solved far below it.
NEWTON_TOLERANCE = 1e-13


@dataclass
class FloquetAnalysis:
    """The Floquet analysis of a periodic motion (:func:`floquet`).

    Attributes:
        period: T (s).
        state: the start state (time t0) of the periodic motion, on the constraints.
        monodromy: Phi (2 n x 2 n): (z, z_dot)(t0 + T) = Phi (z, z_dot)(t0) for the small
            motions in the independent coordinates z.
        multipliers: the eigenvalues mu of Phi, largest |mu| first.
        vectors: the eigenvectors of Phi (columns, in (z, z_dot)), in the order of
            `multipliers`.
        basis: B (coordinates x n): the change of the coordinates q = q0 + B z at t0.
        periodicity: the largest change of the start state over one period (its
            coordinates and rates, local as z, relative to max(1, their size)).
        independent: the coordinates z by body and kind.
    """

    period: float
    state: State
    monodromy: Array
    multipliers: NDArray[np.complex128]
    vectors: NDArray[np.complex128]
    basis: Array
    periodicity: float
    independent: list[str] = field(default_factory=list)
    #: The solver of the runs (the default's spectral radius lowered to
    #: :data:`FALLBACK_SPECTRAL_RADIUS` if a run failed at :data:`SPECTRAL_RADIUS`).
    solver: Any = None
    #: |s| h of the stiffest mode of the linearization at the start (0 where not found), by
    #: which the default solver's spectral radius was chosen (:data:`UNRESOLVED_LIMIT`).
    stiffest: float = 0.0
    #: A run of the default solver diverged, and every run was made again at
    #: :data:`FALLBACK_SPECTRAL_RADIUS`.
    fallback: bool = False

    @property
    def exponents(self) -> NDArray[np.complex128]:
        """The characteristic exponents log(mu) / T (1/s): their real parts the rates of
        growth (positive: unstable), their imaginary parts the frequencies in (-pi/T, pi/T]
        (known up to multiples of 2 pi / T)."""
        return np.log(self.multipliers.astype(complex)) / self.period

    @property
    def drifts(self) -> NDArray[np.bool_]:
        """Which multipliers are a split double 1: a motion that drifts without growing (the
        angle of a free spin, the phase of a free oscillation, where the monodromy holds a
        Jordan block [[1, T], [0, 1]]). The difference quotients' round-off delta splits such
        a block into 1 +- sqrt(T delta) (a wheel spinning freely at 100 rad/s: 1.0018 and
        0.9982), with nearly parallel eigenvectors, which a genuine pair of growing and
        decaying motions does not have: real multipliers within :data:`DRIFT_SPREAD` of 1
        whose eigenvectors are within :data:`DRIFT_COSINE` of parallel to another's."""
        mu = self.multipliers
        near = np.flatnonzero((np.abs(mu - 1.0) <= DRIFT_SPREAD) & (np.abs(mu.imag) <= 1e-12))
        drifts = np.zeros(len(mu), dtype=bool)
        if len(near) < 2:
            return drifts
        vectors = self.vectors[:, near] / np.linalg.norm(self.vectors[:, near], axis=0)
        cosine = np.abs(vectors.conj().T @ vectors)
        np.fill_diagonal(cosine, 0.0)
        drifts[near] = np.max(cosine, axis=1) >= DRIFT_COSINE
        return drifts

    @property
    def neutral(self) -> float:
        """The distance from the unit circle within which a multiplier is neutral: the larger
        of :data:`NEUTRAL` and the :attr:`periodicity` (the runs' error shows in both)."""
        return max(NEUTRAL, self.periodicity)

    @property
    def unstable_directions(self) -> int:
        """How many multipliers lie outside the unit circle by more than :attr:`neutral`
        (a complex pair counted once), those of a drift (:attr:`drifts`) left out."""
        outside = (np.abs(self.multipliers) > 1.0 + self.neutral) & ~self.drifts
        return int(np.sum(self.multipliers[outside].imag >= 0.0))

    @property
    def stable(self) -> bool:
        """True when no multiplier lies outside the unit circle by more than :attr:`neutral`
        (but drifts, :attr:`drifts`): the small motions about the periodic one do not grow."""
        return self.unstable_directions == 0

    def shapes(self) -> NDArray[np.complex128]:
        """The eigenvectors as changes of the coordinates q at t0 (B times their z part)."""
        n = self.basis.shape[1]
        return self.basis @ self.vectors[:n]


def floquet(
    system: Any,
    state: State,
    period: float,
    step_size: float,
    *,
    solver: Any = None,
    perturbation: float = 1e-6,
    periodicity: float = PERIODICITY,
    progress: bool | Callable[[int, int], object] | None = None,
    workers: int | None = None,
) -> FloquetAnalysis:
    """The Floquet analysis of the periodic motion of `system` (a :class:`flexmbd.System` or
    compiled model) through `state` with `period` T (s): the monodromy matrix over one
    period, its multipliers and the stability (see the module).

    `state`: a state on the periodic motion (``result.state(k)`` of a run that has settled
    onto it, or one built by hand: its coordinates on the constraints, its velocities on the
    velocity constraints). `step_size`: the runs' step (s); they take `solver` (default
    generalized-alpha of spectral radius 0.99, Newton's tolerance 1e-13, fixed steps, the
    Newton matrix refreshed every iteration: the differences of the runs must not see their
    solver's tolerances or step changes; if one of its runs diverges, all are made again at
    spectral radius 0.9, see ``analysis.solver``). `perturbation`: eps, the displacement of each
    independent coordinate (m, rad, elastic coordinates) and, times 2 pi / T, of its
    velocity: small against the motions' nonlinearity (the beams of the flexible double
    pendulum, geometric stiffness on, put 2e-5 into |mu| at 1e-5, 4e-8 at 1e-6), large
    against the runs' tolerance (their noise grows as 1 / eps: 1e-7 at 3e-7).
    `periodicity`: the largest change over one period of the start state (any coordinate
    or rate, local as z: relative to max(1, its size)) taken as periodic.
    `progress`: True shows a progress bar of the columns of Phi (two runs each), a
    function is called as ``progress(done, total)``. `workers`: the runs made at once, in
    threads of this process (the runs release the interpreter; default: the processors
    this process may use, at most the columns); the monodromy matrix is the same for any
    number.

    Raises `InvalidParameterError` for a period, step or perturbation that is not positive
    and finite, a state of another model, or a state that does not come back after a period
    (naming the coordinate that changed most), `ArgumentTypeError` for a state that is no
    :class:`flexmbd.State`."""
    from .analysis import _check_state, _model

    model = _model(system, "system")
    if not isinstance(state, State):
        raise ArgumentTypeError(
            f"floquet: state must be a flexmbd.State (result.state(k), or built by hand), got "
            f"{type(state).__name__}",
            item="state",
        )
    period = _positive(period, "period")
    step_size = _positive(step_size, "step_size")
    perturbation = _positive(perturbation, "perturbation")
    periodicity = _positive(periodicity, "periodicity")
    workers = _workers(workers)
    if step_size >= period:  # (it failed the periodicity check, blaming the state)
        raise InvalidParameterError(
            f"floquet: step_size {step_size:g} s must be below the period {period:g} s (a "
            "period takes hundreds of steps: the multipliers carry the runs' error)",
            item="step_size",
        )
    nc = model.constraint_count
    if state.multipliers is None:  # (a state built by hand: the check needs the sizes)
        state = dataclasses.replace(state, multipliers=np.zeros(nc))
    if state.accelerations is None:
        state = dataclasses.replace(state, accelerations=np.zeros(model.coordinate_count))
    _check_state(model, state, "floquet")
    default, stiffest, fallback = solver is None, 0.0, False
    if default:
        spectral_radius, stiffest = _damping_the_unresolved(model, state, period, step_size)
        solver = _default_solver(spectral_radius)
    chart = _Chart(model, state)
    n = chart.size
    end = state.time + period
    scales = np.concatenate(
        [np.full(n, perturbation), np.full(n, perturbation * 2 * np.pi / period)]
    )

    try:
        monodromy, change, worst = _monodromy(
            model, chart, end, step_size, solver, scales, period, periodicity, progress, workers
        )
    except (NewtonDivergedError, NonFiniteError):
        if not default:
            raise
        # Unresolved modes hardly damped at 0.99 can run away (see FALLBACK_SPECTRAL_RADIUS):
        # the whole analysis again, every run with the same, more damping solver.
        solver = _default_solver(min(FALLBACK_SPECTRAL_RADIUS, spectral_radius))
        fallback = True
        monodromy, change, worst = _monodromy(
            model, chart, end, step_size, solver, scales, period, periodicity, progress, workers
        )
    values, vectors = np.linalg.eig(monodromy)
    order = np.lexsort((values.imag, -np.abs(values)))
    return FloquetAnalysis(
        period=period,
        state=chart.start,
        monodromy=monodromy,
        multipliers=values[order],
        vectors=vectors[:, order],
        basis=chart.basis,
        periodicity=float(change[worst]) if len(change) else 0.0,
        independent=list(chart.names),
        solver=solver,
        stiffest=stiffest,
        fallback=fallback,
    )


def _damping_the_unresolved(
    model: _core.Model, state: State, period: float, step_size: float
) -> tuple[float, float]:
    """The default solver's spectral radius: :data:`SPECTRAL_RADIUS`, lowered where the
    modes the steps do not resolve would not die away within the period (see
    :data:`UNRESOLVED_LIMIT`); and |s| h of the stiffest mode of the linearization at the
    start state, by which it was chosen (0 where the linearization failed)."""
    from .analysis import linearize
    from .errors import FlexmbdError

    try:
        values = linearize(model, state).eigenvalues()[0]
    except (FlexmbdError, np.linalg.LinAlgError):
        return SPECTRAL_RADIUS, 0.0  # (a state the linearization refuses: the runs will say)
    stiffest = float(np.max(np.abs(values), initial=0.0)) * step_size
    steps = period / step_size
    if stiffest * SPECTRAL_RADIUS**steps <= UNRESOLVED_LIMIT:
        return SPECTRAL_RADIUS, stiffest
    return float((UNRESOLVED_DECAY / stiffest) ** (1.0 / steps)), stiffest


def _default_solver(spectral_radius: float) -> Any:
    """The default solver of the runs (see :func:`floquet`) at `spectral_radius`."""
    from ._boundary import GeneralizedAlpha

    return GeneralizedAlpha(
        spectral_radius=spectral_radius,
        newton_tolerance=NEWTON_TOLERANCE,
        step_control="fixed",
        jacobian="full",
    )


def _monodromy(
    model: Any,
    chart: _Chart,
    end: float,
    step_size: float,
    solver: Any,
    scales: Array,
    period: float,
    periodicity: float,
    progress: Any,
    workers: int,
) -> tuple[Array, Array, int]:
    """The monodromy matrix from the runs with `solver` (see :func:`floquet`), with the
    change of the start state over the period and its largest entry; refuses a state that
    does not come back."""
    from .simulation import simulate

    n = chart.size

    def run(start: State, shown: bool = False) -> Array:
        result = simulate(
            model,
            end,
            step_size,
            initial_state=start,
            solver=solver,
            output_interval=period,
            progress=True if shown else None,
        )
        return chart.local(result.state(-1))

    # Periodic: every coordinate back (the drivers' too: a wrong period leaves the hanging
    # pendulum as it was and its shaken support elsewhere), relative to max(1, its size).
    # (with a progress bar, this first run shows one too: with many steps it was silent)
    reference = run(chart.start, shown=progress is True)
    start = chart.local(chart.start)
    change = np.abs(reference - start) / np.maximum(1.0, np.abs(start))
    worst = int(np.argmax(change)) if len(change) else 0
    if len(change) and not change[worst] <= periodicity:
        half = len(change) // 2
        what = chart.label(worst % half) + (" (its rate)" if worst >= half else "")
        raise InvalidParameterError(
            f"floquet: the state does not come back after the period {period:g} s: "
            f"{what} changed by {change[worst]:.3g} (relative; more than {periodicity:g}); "
            "start from a state of the periodic motion (run until the transients have died "
            "away and take result.state(k)), or check the period",
            item="state",
        )

    def column(j: int) -> Array:
        offset = np.zeros(2 * n)
        offset[j] = scales[j]
        ahead = run(chart.state(offset[:n], offset[n:]))
        behind = run(chart.state(-offset[:n], -offset[n:]))
        return chart.difference(ahead, behind) / (2.0 * scales[j])

    monodromy = np.zeros((2 * n, 2 * n))
    columns = _columns(column, 2 * n, min(workers, 2 * n))
    for j, values in track_progress(columns, progress, "floquet", total=2 * n, unit="columns"):
        monodromy[:, j] = values
    return monodromy, change, worst


def _workers(workers: Any) -> int:
    """The runs at once: `workers` checked, or the processors this process may use."""
    if workers is None:
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # (not on macOS and Windows)
            return max(1, os.cpu_count() or 1)
    if isinstance(workers, bool) or not isinstance(workers, int | np.integer) or workers < 1:
        raise InvalidParameterError(
            f"floquet: workers must be a whole number of at least 1 (or None: the processors "
            f"this process may use), got {workers!r}",
            item="workers",
        )
    return int(workers)


def _columns(
    column: Callable[[int], Array], count: int, workers: int
) -> Iterator[tuple[int, Array]]:
    """Yields (j, column(j)) for j < count, in the order they are done: with `workers` > 1
    from that many threads (the runs release the interpreter). The first failure stops the
    columns not yet begun and is raised; so is an interruption (Ctrl-C) of the waiting."""
    if workers == 1:
        for j in range(count):
            yield j, column(j)
        return
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="floquet")
    try:
        pending = {pool.submit(column, j): j for j in range(count)}
        for done in as_completed(pending):
            yield pending[done], done.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _positive(value: Any, name: str) -> float:
    value = number(value, name)  # (finite)
    if not value > 0.0:
        raise InvalidParameterError(
            f"floquet: {name} must be positive and finite, got {value}", item=name
        )
    return value


class _Chart:
    """The independent coordinates z of a model about a state and their rates: builds the
    states on the constraints at (z, z_dot) and measures a state's (z, z_dot). The local
    coordinates y of :func:`flexmbd.analysis._frame_transform` (frames: change of origin and
    small rotation in their own axes; the rest as they are), of which the independent ones
    (:func:`flexmbd.analysis.local_partition`) are z; the dependent ones are solved from the
    constraints and the velocity constraints."""

    def __init__(self, model: _core.Model, state: State) -> None:
        from .analysis import _constraint_jacobian, _frame_transform, local_partition

        self.model = model
        self.layout = model.describe()
        self.time = state.time
        self.q0 = np.asarray(state.coordinates, dtype=float)
        # Per body: its name, the offset of its frame's [R, p] (None without a frame), the
        # offset and count of its other coordinates, and its first local coordinate.
        self.bodies: list[tuple[str, int | None, int, int, int]] = []
        column = 0
        for b in self.layout["bodies"]:
            o, count = b["offset"], b["count"]
            frame = b["kind"] in ("rigid", "flexible") and count >= 7
            rest = count - 7 if frame else count
            self.bodies.append((b["name"], o if frame else None, o + count - rest, rest, column))
            column += rest + (6 if frame else 0)
        transform, elastic = _frame_transform(self.layout, self.q0)
        jacobian = _constraint_jacobian(model, self.time, self.q0) @ transform
        self.dependent, local = local_partition(jacobian, elastic)
        self.independent = np.setdiff1d(np.arange(transform.shape[1]), self.dependent)
        self.size = len(self.independent)
        self.names = [self.label(k) for k in self.independent]
        self.basis = transform @ local
        self.rates0 = self._rates(self.q0, np.asarray(state.velocities, dtype=float))
        self.discrete = state.discrete
        self.start = self.state(np.zeros(self.size), np.zeros(self.size))

    def label(self, column: int) -> str:
        """The local coordinate `column` by body and kind."""
        for name, frame, _, _, first in reversed(self.bodies):
            if column < first:
                continue
            c = column - first
            if frame is not None and c < 6:
                kind = "displacement" if c < 3 else "rotation"
                return f"body '{name}' {kind} {('x', 'y', 'z')[c % 3]} (own axes)"
            return f"body '{name}' coordinate {c - (6 if frame is not None else 0)}"
        return f"coordinate {column}"

    def _rates(self, q: Array, qd: Array) -> Array:
        """The local rates y_dot of the velocities `qd` at `q` (frames: the velocity of the
        origin and the angular velocity in their own axes)."""
        rates = np.zeros(len(self.independent) + len(self.dependent))
        for _, frame, o, rest, c in self.bodies:
            if frame is not None:
                p, p_dot = q[frame + 3 : frame + 7], qd[frame + 3 : frame + 7]
                rates[c : c + 3] = euler_parameters_to_matrix(p).T @ qd[frame : frame + 3]
                rates[c + 3 : c + 6] = angular_velocity(p, p_dot, "body")
                c += 6
            rates[c : c + rest] = qd[o : o + rest]
        return rates

    def _moved(self, q: Array, y: Array) -> Array:
        """q moved by the local coordinates y (frames turned by exp(y~) in their own axes)."""
        from scipy.spatial.transform import Rotation

        moved = q.copy()
        for _, frame, o, rest, c in self.bodies:
            if frame is not None:
                p = q[frame + 3 : frame + 7]
                a = euler_parameters_to_matrix(p)
                moved[frame : frame + 3] += a @ y[c : c + 3]
                turned = a @ Rotation.from_rotvec(y[c + 3 : c + 6]).as_matrix()
                x, yy, z, w = Rotation.from_matrix(turned).as_quat()
                p_new = np.array([w, x, yy, z])
                moved[frame + 3 : frame + 7] = p_new if p_new @ p >= 0.0 else -p_new
                c += 6
            moved[o : o + rest] += y[c : c + rest]
        return moved

    def _offsets(self, q: Array, reference: Array) -> Array:
        """The local coordinates y of `q` from `reference` (frames: the change of origin and
        the rotation vector of A_ref^T A, in the reference's axes)."""
        from scipy.spatial.transform import Rotation

        y = np.zeros(len(self.independent) + len(self.dependent))
        for _, frame, o, rest, c in self.bodies:
            if frame is not None:
                a0 = euler_parameters_to_matrix(reference[frame + 3 : frame + 7])
                a1 = euler_parameters_to_matrix(q[frame + 3 : frame + 7])
                y[c : c + 3] = a0.T @ (q[frame : frame + 3] - reference[frame : frame + 3])
                y[c + 3 : c + 6] = Rotation.from_matrix(a0.T @ a1).as_rotvec()
                c += 6
            y[c : c + rest] = q[o : o + rest] - reference[o : o + rest]
        return y

    def state(self, z: Array, z_dot: Array) -> State:
        """The state at t0 with independent coordinates z and rates z_dot (from the start
        state's), the dependent ones on the constraints and velocity constraints."""
        from .analysis import _constraint_jacobian, _frame_transform

        model, t = self.model, self.time
        nq, nc = model.coordinate_count, model.constraint_count
        y = np.zeros(len(self.independent) + len(self.dependent))
        y[self.independent] = z
        q = self._moved(self.q0, y)
        zero = np.zeros(nq)
        scale = max(1.0, float(np.max(np.abs(q), initial=0.0)))
        previous = np.inf
        for _ in range(PROJECTION_ITERATIONS):
            if nc == 0 or len(self.dependent) == 0:
                break
            residual = model.evaluate(t, q, zero, zero, np.zeros(nc))["residual"][nq:]
            size = float(np.max(np.abs(residual)))
            if size <= 1e-14 * scale or (size <= PROJECTED * scale and size > 0.5 * previous):
                break  # (on the constraints, or at their round-off)
            previous = size
            transform, _ = _frame_transform(self.layout, q)
            jacobian = _constraint_jacobian(model, t, q) @ transform
            step = np.zeros_like(y)
            step[self.dependent] = -np.linalg.lstsq(
                jacobian[:, self.dependent], residual, rcond=None
            )[0]
            q = self._moved(q, step)
        else:
            if nc and len(self.dependent):
                moved = float(np.max(np.abs(z), initial=0.0))
                raise InvalidParameterError(
                    f"floquet: the start moved by the perturbation ({moved:.3g}) "
                    f"could not be put back on the constraints in {PROJECTION_ITERATIONS} "
                    f"iterations (residual {previous:.3g}); give a smaller perturbation, or a "
                    "state away from a singular configuration",
                    item="perturbation",
                )
        transform, _ = _frame_transform(self.layout, q)
        rates = np.zeros_like(y)
        rates[self.independent] = self.rates0[self.independent] + z_dot
        if nc and len(self.dependent):
            jacobian = _constraint_jacobian(model, t, q) @ transform
            ev = model.evaluate(t, q, zero, zero, np.zeros(nc))
            right = -(
                ev["constraint_rate"] + jacobian[:, self.independent] @ rates[self.independent]
            )
            rates[self.dependent] = np.linalg.lstsq(jacobian[:, self.dependent], right, rcond=None)[
                0
            ]
        qd = transform @ rates  # (frames: dR = A dR_bar, dp = 1/2 G^T dpi_bar)
        from .system import identity_of

        return State(
            t,
            q,
            qd,
            layout=self.layout,
            flexible=model.flexible_bodies,
            system_identity=identity_of(model),
            discrete=self.discrete,
        )

    def local(self, state: State) -> Array:
        """(y, y_dot) of `state`: its local coordinates from the start's and its local rates,
        all of them (the independent ones are taken by :meth:`difference`)."""
        q = np.asarray(state.coordinates, dtype=float)
        qd = np.asarray(state.velocities, dtype=float)
        return np.concatenate([self._offsets(q, self.q0), self._rates(q, qd)])

    def difference(self, a: Array, b: Array) -> Array:
        """(z, z_dot) of the local values `a` less those of `b`."""
        m = len(self.independent) + len(self.dependent)
        d = a - b
        return np.concatenate([d[:m][self.independent], d[m:][self.independent]])
