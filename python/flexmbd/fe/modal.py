"""Modal reduction of deformable bodies (seed section 3, eq. 18): free-free modes, fixed-interface
modes, Craig-Bampton bases with nodal, rigid (RBE2-like) or averaged (RBE3-like) interfaces, and
the invariants of motion in modal coordinates.

Large eigenproblems K x = w^2 M x are solved by a block Davidson method with thick restarts
(`block_davidson_eigenpairs`) preconditioned by a sparse Cholesky factorization in Rust
(`flexmbd._core.SymmetricFactor`, nested dissection of the mesh): in double precision it is the
block shift-invert Krylov method; in single precision (half the memory, for large bodies) it
needs no inner iterations. Static solves with a single-precision factor use it as the
preconditioner of conjugate gradients (`Inverse`). Every basis returned is
mass-normalized; Craig-Bampton bases are orthonormalized and diagonalized (their reduced
eigenproblem is solved), so that the modal mass matrix is the identity and the modal stiffness
matrix is diagonal.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..errors import InvalidModelError, InvalidParameterError, ModeCountWarning
from .interface import Interface, make_interface

#: Below this many coordinates eigenproblems are solved densely.
DENSE_LIMIT = 300

#: Interface kinds of Craig-Bampton bases.
INTERFACE_KINDS = ("nodal", "rbe2", "rbe3")


# Factorizations ---------------------------------------------------------------------------------


def lower_triangle(matrix: sp.spmatrix) -> sp.csc_matrix:
    """The lower triangle (diagonal included) of a sparse matrix, CSC with sorted indices; a
    matrix that is already lower triangular CSC with sorted indices is returned as it is (no
    copy), one with unsorted indices is sorted in a copy (a body's matrices are read-only)."""
    if sp.isspmatrix_csc(matrix) or isinstance(matrix, sp.csc_array):
        columns = np.repeat(np.arange(matrix.shape[1]), np.diff(matrix.indptr))
        if np.all(matrix.indices >= columns):
            if not matrix.has_sorted_indices:
                matrix = matrix.copy()
                matrix.sort_indices()
            return matrix
    lower = sp.tril(matrix, format="csc")
    lower.sort_indices()
    return lower


def factorize(
    matrix: sp.spmatrix,
    *,
    dofs: NDArray[np.int64] | None = None,
    nodes: NDArray[np.float64] | None = None,
    dofs_per_node: int = 3,
    positive: int | None = None,
    single: bool = False,
    name: str = "matrix",
    threads: int | None = None,
) -> Any:
    """Sparse symmetric factorization of `matrix` (Cholesky, or quasi-definite LDL^T when
    `positive` gives the size of the definite block; `single`: Cholesky in single precision).
    Only the lower triangle of `matrix` is read (it may be given alone, see `lower_triangle`).
    With `nodes`, the unknowns are the nodal coordinates `dofs` (all when None) of a body with
    `dofs_per_node`, and the ordering is a nested dissection of the mesh; unknowns beyond
    len(dofs) (multipliers) are ordered last. `threads`: of the factorization and its solves
    (default: every core)."""
    n = matrix.shape[0]
    kwargs: dict[str, Any] = {}
    if nodes is not None:
        dofs = np.arange(len(nodes) * dofs_per_node) if dofs is None else np.asarray(dofs)
        dof_nodes = np.full(n, -1, dtype=np.int64)
        dof_nodes[: len(dofs)] = dofs // dofs_per_node
        kwargs = {"dof_nodes": dof_nodes, "positions": np.ascontiguousarray(nodes, dtype=float)}
    lower = lower_triangle(matrix)
    return _core.SymmetricFactor(
        n,
        lower.indptr.astype(np.int64),
        lower.indices.astype(np.int64),
        np.ascontiguousarray(lower.data, dtype=float),
        positive=positive,
        single=single,
        threads=threads or os.cpu_count() or 1,
        name=name,
        **kwargs,
    )


#: Bodies with more coordinates than this use single-precision factors with precision="auto".
SINGLE_PRECISION_ABOVE = 250_000


def _use_single(precision: str, n: int) -> bool:
    if precision not in ("double", "single", "auto"):
        raise InvalidParameterError(
            f"precision must be 'double', 'single' or 'auto', got {precision!r}"
        )
    return precision == "single" or (precision == "auto" and n > SINGLE_PRECISION_ABOVE)


class Inverse:
    """Applies A^-1 for a symmetric positive definite sparse A: with a double-precision
    Cholesky factor, or, with `single`, by conjugate gradients preconditioned with a
    single-precision factor (half the memory; a few iterations per solve), to a relative
    residual of `tolerance` per column. The factor keeps A itself (`multiply`), so that the
    caller may drop its copy."""

    #: Columns solved together by conjugate gradients (bounds the memory of the iteration).
    CHUNK = 8

    def __init__(
        self,
        matrix: sp.spmatrix,
        *,
        single: bool = False,
        tolerance: float = 1e-11,
        name: str = "matrix",
        **ordering: Any,
    ):
        self.shape = matrix.shape
        self.single = single
        self.tolerance = tolerance
        self.name = name
        self.factor = factorize(matrix, single=single, name=name, **ordering)
        self.iterations = 0

    @property
    def factor_bytes(self) -> int:
        return int(self.factor.factor_bytes)

    def multiply(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """A x (columns)."""
        return self.factor.multiply(x)

    def __matmul__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.multiply(x)

    def precondition(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        """A^-1 b approximately: one solve with the factor (exact in double precision, to
        about 1e-7 times the condition number in single precision)."""
        return self.factor.solve(b)

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        if not self.single:
            return self.factor.solve(b)
        rhs = b.reshape(b.shape[0], -1)
        x = np.empty_like(rhs)
        for first in range(0, rhs.shape[1], self.CHUNK):
            columns = slice(first, first + self.CHUNK)
            x[:, columns] = self._conjugate_gradients(np.ascontiguousarray(rhs[:, columns]))
        return x.reshape(b.shape)

    def _conjugate_gradients(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        norms = np.linalg.norm(b, axis=0)
        norms[norms == 0.0] = 1.0
        x = self.factor.solve(b)
        r = b - self.factor.multiply(x)
        z = self.factor.solve(r)
        p = z
        rz = np.einsum("ij,ij->j", r, z)
        for _ in range(200):
            residual = np.linalg.norm(r, axis=0) / norms
            if residual.max() <= self.tolerance:
                return x
            self.iterations += 1
            q = self.factor.multiply(p)
            pq = np.einsum("ij,ij->j", p, q)
            alpha = np.divide(rz, pq, out=np.zeros_like(rz), where=pq != 0.0)
            x += p * alpha
            q *= alpha
            r -= q
            del q
            z = self.factor.solve(r)
            rz_new = np.einsum("ij,ij->j", r, z)
            beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0.0)
            p *= beta
            p += z
            rz = rz_new
        raise InvalidModelError(
            f"conjugate gradients with the single-precision factor of the {self.name} did not "
            f"reach a relative residual of {self.tolerance:.0e} (reached {residual.max():.1e}); "
            "the matrix is too ill-conditioned for single precision: use precision='double'",
            item=self.name,
        )


class _Restricted:
    """Products with the block A[keep][:, keep] of a sparse matrix without forming it (a copy
    of the size of A for large bodies), a few columns at a time."""

    CHUNK = 8

    def __init__(self, matrix: sp.spmatrix, keep: NDArray[np.int64]):
        self.matrix = matrix
        self.shape = (len(keep), len(keep))
        # Runs of consecutive kept indices: copies by slices (interfaces leave few gaps).
        breaks = np.flatnonzero(np.diff(keep) != 1) + 1
        starts = np.concatenate([[0], breaks])
        ends = np.concatenate([breaks, [len(keep)]])
        self.runs = [(int(a), int(b), int(keep[a])) for a, b in zip(starts, ends, strict=True)]

    def __matmul__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        columns = x.reshape(self.shape[0], -1)
        out = np.empty(columns.shape)
        full = np.zeros((self.matrix.shape[0], min(self.CHUNK, columns.shape[1])))
        for first in range(0, columns.shape[1], self.CHUNK):
            part = slice(first, first + self.CHUNK)
            width = columns[:, part].shape[1]
            for a, b, at in self.runs:
                full[at : at + b - a, :width] = columns[a:b, part]
            product = self.matrix @ full[:, :width]
            for a, b, at in self.runs:
                out[a:b, part] = product[at : at + b - a]
        return out.reshape(x.shape)


# Eigenproblems ----------------------------------------------------------------------------------


def _mass_normalize(vectors: NDArray, m: Any) -> NDArray:
    norms = np.sqrt(np.einsum("ij,ij->j", vectors, m @ vectors))
    return vectors / norms


def _m_orthonormalize(
    w: NDArray[np.float64],
    m: Any,
    previous: NDArray[np.float64],
    keep: Any = None,
) -> NDArray[np.float64]:
    """Columns of w (overwritten) made M-orthogonal to the M-orthonormal columns `previous` and
    M-orthonormal among themselves (directions lost to round-off dropped): classical
    Gram-Schmidt twice, then the eigen-decomposition of the Gram matrix. A second round restores
    the orthogonality that normalizing small remainders loses (when much of w cancelled or the
    block is nearly dependent); `keep` (a projector onto constraints) is applied before each
    normalization, so that round-off amplified by it stays in the constraint space. M V is not
    stored: it is recomputed, which costs little beside the solves and saves a copy of the
    basis."""
    for round_ in range(2):
        before = 0.0
        for pass_ in range(2 if previous.shape[1] else 0):
            mw = m @ w
            if pass_ == 0:
                before = float(np.einsum("ij,ij->j", w, mw).max())
            coefficients = previous.T @ mw
            del mw
            w -= previous @ coefficients
        if keep is not None:
            w = keep(w)
        gram = w.T @ (m @ w)
        values, vectors = np.linalg.eigh(0.5 * (gram + gram.T))
        largest = max(values.max(), 1e-300)
        threshold = 1e-12 * largest if round_ == 0 else 0.5
        kept = values > threshold
        step = vectors[:, kept] / np.sqrt(values[kept])
        w = w @ step
        # Orthogonality lost in normalizing is about 1e-16 / sqrt(smallest / largest norm^2).
        if round_ == 0 and (not kept.any() or values[kept].min() > 1e-6 * max(largest, before)):
            break
    return w


#: Ritz vectors formed at a time for the residuals of `block_davidson_eigenpairs`.
_RESIDUAL_CHUNK = 8


def block_davidson_eigenpairs(
    k: Any,
    m: Any,
    count: int,
    precondition: Any,
    *,
    shift: float = 0.0,
    block: int | None = None,
    steps: int = 3,
    tolerance: float = 1e-8,
    iterations: int = 200,
    project: Any = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The `count` lowest eigenpairs of K x = lambda M x by a block Davidson iteration with
    thick restarts. The basis V (M-orthonormal) starts from `block` vectors and grows by the
    preconditioned residuals T (K X - M X Lambda) of the `block` lowest Ritz pairs (X, Lambda)
    of (K, M) in V; after `steps` expansions it restarts from X. `precondition` applies
    T ~ (K - shift M)^-1 to a block of columns: with an exact inverse the basis is the block
    shift-invert Krylov space (T r = (lambda - shift) S x - x with S = (K - shift M)^-1 M), and
    an approximate one (a single-precision factor) needs no inner iteration: the residuals are
    exact, so the Ritz pairs converge to the exact ones, only a little more slowly. Converged
    when every wanted pair has |T r|_M < `tolerance` (|x|_M = 1): the residual of the
    shift-invert operator, as in ARPACK, insensitive to high-frequency round-off that K would
    amplify. `k` and `m` need only products with blocks of columns (`@`). For eigenproblems
    with constraints G x = 0 (`precondition` then maps into G x = 0), `project` is the
    projector onto G x = 0: it keeps the basis in the constraint space against round-off (where
    rigid motions of zero energy would creep in). Memory: the basis, (steps + 1) blocks of
    vectors. Returns ascending eigenvalues and M-orthonormal vectors."""
    n = k.shape[0]
    block = block or max(count + 4, 8)
    keep = project or (lambda y: y)
    rng = np.random.default_rng(20261122)
    start = keep(precondition(m @ rng.standard_normal((n, block))))
    v = np.empty((n, block * (steps + 1)))
    w = _m_orthonormalize(start, m, v[:, :0], project)
    used = w.shape[1]
    v[:, :used] = w
    h = w.T @ (k @ w)
    del start, w
    history: list[float] = []
    residual = np.inf
    for _ in range(iterations):
        values, y = sla.eigh(0.5 * (h + h.T))
        values = values[:block]
        # The residuals K X - M X Lambda of the Ritz vectors X = V Y, a few columns at a time
        # (X is not kept: memory of large bodies).
        r = np.empty((n, block))
        for first in range(0, block, _RESIDUAL_CHUNK):
            columns = slice(first, min(first + _RESIDUAL_CHUNK, block))
            x = v[:, :used] @ y[:, columns]
            r[:, columns] = k @ x
            x = m @ x
            x *= values[columns]
            r[:, columns] -= x
            del x
        t = keep(precondition(r))
        del r
        mt = m @ t
        norms = np.sqrt(np.abs(np.einsum("ij,ij->j", t, mt)))
        del mt
        residual = float(norms[:count].max())
        history.append(residual)
        # Converged, or stagnating at the round-off floor (which grows with the condition
        # number of K - shift M): no progress in the last four iterations.
        stalled = len(history) > 4 and residual > 0.5 * min(history[-5:-1])
        if residual < tolerance or (residual < 1e3 * tolerance and stalled):
            return values[:count], v[:, :used] @ y[:, :count]
        if used + block > v.shape[1]:
            x = v[:, :used] @ y[:, :block]
            v[:, : x.shape[1]] = x
            used = x.shape[1]
            h = x.T @ (k @ x)
            del x
        # Directions of unit length; those of converged pairs add nothing.
        active = norms > 0.1 * tolerance
        if not active.all():
            t = t[:, active]
        t /= norms[active]
        w = _m_orthonormalize(t, m, v[:, :used], project)
        del t
        if w.shape[1] == 0:  # the residuals lie in the basis: exact to round-off
            return values[:count], v[:, :used] @ y[:, :count]
        kw = k @ w
        coupling = v[:, :used].T @ kw
        h = np.block([[h, coupling], [coupling.T, w.T @ kw]])
        v[:, used : used + w.shape[1]] = w
        used += w.shape[1]
        del w, kw
    raise InvalidModelError(
        f"the eigensolver did not converge: relative residual {residual:.1e} after "
        f"{iterations} iterations for {count} modes",
        item="eigenproblem",
    )


def eigenpairs(
    k: Any,
    m: Any,
    count: int,
    *,
    shift: float = 0.0,
    solve: Any = None,
    dense_projection: NDArray[np.float64] | None = None,
    project: Any = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The `count` eigenpairs of K x = lambda M x nearest to `shift` from above, sorted and
    mass-normalized. `solve(y)` applies (K - shift M)^-1, or an approximation of it, to blocks
    of columns (see
    `block_davidson_eigenpairs`, also for `project`); small problems are solved densely (within
    the columns of `dense_projection` when given: a basis of the admissible motions)."""
    n = k.shape[0]
    if count < 1:
        raise InvalidParameterError(f"at least one mode is needed, got {count}", item="mode_count")
    if dense_projection is not None or n <= DENSE_LIMIT:
        z = np.eye(n) if dense_projection is None else dense_projection
        kz = z.T @ (k @ z)
        mz = z.T @ (m @ z)
        if count > kz.shape[0]:
            raise InvalidParameterError(
                f"{count} modes requested of {kz.shape[0]} coordinates", item="mode_count"
            )
        values, vectors = sla.eigh(
            0.5 * (kz + kz.T), 0.5 * (mz + mz.T), subset_by_index=[0, count - 1]
        )
        return _rayleigh_ritz(k, m, z @ vectors)
    if count > n // 4:
        raise InvalidParameterError(
            f"{count} modes requested of a {n}-coordinate body: at most {n // 4}",
            item="mode_count",
        )
    if solve is None:
        raise InvalidParameterError("a large eigenproblem needs the factorization of K - shift M")
    _, vectors = block_davidson_eigenpairs(k, m, count, solve, shift=shift, project=project)
    return _rayleigh_ritz(k, m, vectors)


#: Frequencies within this fraction of each other count as one group of equal frequencies
#: (a symmetric section's bending pair; an unstructured mesh of a round shaft splits it by
#: 1e-4 to 1e-3), which `mode_count` should keep whole.
EQUAL_FREQUENCIES = 1e-3


def whole_groups(
    k: Any, m: Any, count: int, what: str, rigid: int = 0, **options: Any
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`eigenpairs` (`count` of them, `options` passed on) with a
    :class:`flexmbd.ModeCountWarning` when the next mode's frequency is within
    :data:`EQUAL_FREQUENCIES` of the last one kept: the count cuts a group of equal
    frequencies. One more mode is computed to tell (none when the problem has no more).
    `what` names the modes in the message; the first `rigid` are rigid-body modes, not
    counted in the `mode_count` it names."""
    try:
        values, vectors = eigenpairs(k, m, count + 1, **options)
    except InvalidParameterError:
        return eigenpairs(k, m, count, **options)
    if count > rigid:
        found = frequencies(values)
        last, following = found[count - 1], found[count]
        if following - last <= EQUAL_FREQUENCIES * following:
            kept = int(np.sum(found[rigid:count] >= following * (1.0 - EQUAL_FREQUENCIES)))
            user = count - rigid
            warnings.warn(
                f"{what}: mode_count {user} keeps {kept} of a group of equal frequencies "
                f"({last:.6g} Hz kept, {following:.6g} Hz left out): which of them is kept is "
                f"arbitrary, and the body is stiffer in the directions left out; take "
                f"mode_count {user + 1} (or more, to keep the group whole) or {user - kept}",
                ModeCountWarning,
                stacklevel=_user_level(),
            )
    return values[:count], vectors[:, :count]


def _user_level() -> int:
    """The `stacklevel` of a warning given by its caller that names the first frame outside
    the flexmbd package (the user's call of build_body, load_body, ...), however deep the
    package's calls are."""
    import inspect

    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame = inspect.currentframe()
    frame = frame.f_back if frame is not None else None  # the caller of warnings.warn
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame = frame.f_back
        level += 1
    return level


def _rayleigh_ritz(k: Any, m: Any, vectors: NDArray) -> tuple[NDArray, NDArray]:
    """The eigenpairs of K and M within the columns of `vectors` (ascending, mass-normalized):
    values that are the modes' own Rayleigh quotients, as the simulation takes K_ff = Phi^T K
    Phi. A solver's eigenvalues can be less accurate than its vectors: for the shells' mass,
    whose rotational entries are 1e-10 of the translational ones, dense eigh gave a first
    eigenvalue 6e-6 off its vector's Rayleigh quotient."""
    kv = vectors.T @ (k @ vectors)
    mv = vectors.T @ (m @ vectors)
    values, y = sla.eigh(0.5 * (kv + kv.T), 0.5 * (mv + mv.T))
    return values, _mass_normalize(vectors @ y, m)


def frequencies(values: NDArray) -> NDArray:
    """Natural frequencies (Hz) of the eigenvalues w^2 (negative round-off clipped to 0)."""
    return np.sqrt(np.clip(values, 0.0, None)) / (2 * np.pi)


def _scale(k: sp.spmatrix, m: sp.spmatrix) -> float:
    """A typical eigenvalue magnitude max(diag K) / max(diag M)."""
    return float(abs(k.diagonal()).max() / max(abs(m.diagonal()).max(), 1e-300))


#: Lowest eigenvalue, relative to `_scale`, under which held modes count as rigid motions.
#: Round-off of a rigid motion's eigenvalue is about 1e-16 times the largest eigenvalue (a
#: few tens of times `_scale`); 1e-10 refused a clamped 1 m x 10 mm x 2 mm aluminium strip
#: of 125 x 5 x 1 hex8, whose first bending eigenvalue (781, 4.45 Hz) is 1e-10 of it.
RIGID_FIXED = 1e-12


def _check_fixed(values: NDArray, scale: float, what: str) -> None:
    if values[0] < RIGID_FIXED * scale:
        raise InvalidModelError(
            f"{what} leave the body free to move rigidly (lowest eigenvalue {values[0]:.3e}); "
            "fix more coordinates or use free-free modes"
        )


def fixed_interface_modes(
    stiffness: sp.spmatrix,
    mass: sp.spmatrix,
    free_dofs: NDArray[np.int64],
    count: int,
    *,
    nodes: NDArray[np.float64] | None = None,
    dofs_per_node: int = 3,
    precision: str = "auto",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The first `count` eigenmodes with the coordinates not in `free_dofs` held (modes over
    `free_dofs`, mass-normalized) and their frequencies (Hz). `nodes` enables the nested
    dissection ordering of the factorization; `precision` ("double", "single", "auto") that
    of the factorization (see `Inverse`)."""
    free_dofs = np.asarray(free_dofs, dtype=np.int64)
    kf = stiffness[free_dofs][:, free_dofs].tocsc()
    mf = mass[free_dofs][:, free_dofs].tocsc()
    solve = None
    if kf.shape[0] > DENSE_LIMIT:
        try:
            inverse = Inverse(
                kf,
                single=_use_single(precision, kf.shape[0]),
                dofs=free_dofs,
                nodes=nodes,
                dofs_per_node=dofs_per_node,
                name="stiffness with the reference conditions",
            )
        except InvalidModelError as error:
            raise InvalidModelError(
                f"the reference conditions leave the body free to move rigidly ({error})",
                item="reference conditions",
            ) from error
        solve = inverse.precondition
    values, vectors = whole_groups(kf, mf, count, "fixed-interface modes", solve=solve)
    _check_fixed(values, _scale(kf, mf), "the reference conditions")
    return vectors, frequencies(values)


def free_free_modes(
    stiffness: sp.spmatrix,
    mass: sp.spmatrix,
    count: int,
    rigid: int = 6,
    *,
    nodes: NDArray[np.float64] | None = None,
    dofs_per_node: int = 3,
    dofs: NDArray[np.int64] | None = None,
    precision: str = "auto",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The first `count` elastic free-free modes (the `rigid` rigid-body modes removed) and
    their frequencies (Hz). `dofs`: the nodal coordinates the matrices hold (default all of
    `nodes`' coordinates), for the ordering of the factorization. Being mass-orthogonal to
    the rigid motions, they satisfy the mean axis (Tisserand) conditions. Raises if the body
    is not free (fewer than `rigid` near-zero frequencies) or has more rigid motions than
    `rigid` (a mechanism or disconnected parts). The shift of the shift-invert iteration is
    slightly negative, so that K - shift M is positive definite although K is singular."""
    n = stiffness.shape[0]
    scale = _scale(stiffness, mass)
    shift = -1e-6 * scale
    solve = None
    if n > DENSE_LIMIT:
        inverse = Inverse(
            stiffness - shift * mass,
            single=_use_single(precision, n),
            nodes=nodes,
            dofs_per_node=dofs_per_node,
            **({} if dofs is None else {"dofs": dofs}),
            name="shifted stiffness K - sigma M",
        )
        solve = inverse.precondition
    values, vectors = whole_groups(
        stiffness, mass, count + rigid, "free-free modes", rigid, shift=shift, solve=solve
    )
    elastic = values[rigid:]
    # A vanishing "elastic" eigenvalue is one rigid motion too many (the bound of
    # `_check_fixed`, which a clamped body's lowest eigenvalue, lower still, passes).
    if elastic[0] < 1e-10 * scale:
        raise InvalidModelError(
            f"the body has more than {rigid} rigid-body motions: eigenvalue {rigid + 1} of "
            f"K x = w^2 M x is {elastic[0]:.3e}, zero at the scale {scale:.3e} of the body "
            f"(n = {n}); free-free modes would take the extra motions as elastic modes of "
            "frequency 0. The mesh has a mechanism (parts joined at a single node or edge) "
            "or disconnected parts",
            item="free-free modes",
        )
    if rigid and values[rigid - 1] > 1e-6 * max(elastic[0], 1e-300):
        raise InvalidModelError(
            f"the body is not free: its {rigid} lowest eigenvalues should vanish, "
            f"got {values[:rigid]} (n = {n})"
        )
    return vectors[:, rigid:], frequencies(elastic)


# Rigid motions and interfaces --------------------------------------------------------------------


def rigid_modes(nodes: NDArray[np.float64], dofs_per_node: int) -> NDArray[np.float64]:
    """The six rigid-body motions in nodal coordinates (n_dofs, 6): translations, then
    infinitesimal rotations u = w x X (rotations also set the rotational coordinates)."""
    nodes = np.asarray(nodes, dtype=float)
    d = dofs_per_node
    n = len(nodes)
    r = np.zeros((n * d, 6))
    for k in range(3):
        r[k::d, k] = 1.0
        w = np.zeros(3)
        w[k] = 1.0
        u = np.cross(w, nodes)
        for c in range(3):
            r[c::d, 3 + k] = u[:, c]
        if d == 6:
            r[3 + k :: d, 3 + k] = 1.0
    return r


def _support_dofs(rigid: NDArray[np.float64]) -> NDArray[np.int64]:
    """Six coordinates whose values fix a rigid motion (R restricted to them is invertible and
    well conditioned): a statically determinate support chosen by pivoted QR."""
    _, _, pivots = sla.qr(rigid.T, mode="economic", pivoting=True)
    return np.sort(pivots[:6])


# Craig-Bampton ---------------------------------------------------------------------------------


def interface_objects(
    interfaces: Sequence[ArrayLike | Interface],
    nodes: NDArray[np.float64],
    elements: Mapping[str, ArrayLike] | None,
    weights: str | Sequence[str | ArrayLike],
    *,
    rotation: bool = True,
    nodal_rotations: bool = False,
) -> list[Interface]:
    """The `Interface`s of Craig-Bampton interfaces given as node indices (or already as
    interfaces), with their members in ascending order (the order of the boundary
    coordinates). `weights`: one weighting for all or one per interface (arrays in the
    order given). `rotation`: whether each must define a rotation (at least three
    non-collinear nodes: averaged interfaces), unless `nodal_rotations` (nodes with
    rotational coordinates) give it about a line of nodes."""
    count = len(interfaces)
    if isinstance(weights, str):
        per: list[Any] = [weights] * count
    else:
        per = list(weights)
        if len(per) != count:
            raise InvalidParameterError(
                f"interface weights: {len(per)} given for {count} interfaces",
                item="interface weights",
            )
    out = []
    for index, (given, how) in enumerate(zip(interfaces, per, strict=True)):
        if isinstance(given, Interface):
            if np.all(np.diff(given.members) > 0):
                out.append(given)
                continue
            given, how = given.members, given.weights
        members = np.asarray(given, dtype=np.int64).ravel()
        order = np.argsort(members, kind="stable")
        if not isinstance(how, str):
            how = np.asarray(how, dtype=float).ravel()
            if how.shape == members.shape:
                how = how[order]
        out.append(
            make_interface(
                nodes,
                elements or {},
                members[order],
                how,
                name=f"interface {index}",
                require_rotation=rotation,
                nodal_rotations=nodal_rotations,
            )
        )
    return out


def _interface_members(
    interfaces: Sequence[ArrayLike | Interface], node_count: int
) -> list[NDArray]:
    members = [
        np.unique(np.asarray(s.members if isinstance(s, Interface) else s, dtype=np.int64))
        for s in interfaces
    ]
    if not members or any(m.size == 0 for m in members):
        raise InvalidModelError("Craig-Bampton needs at least one non-empty interface node set")
    seen = np.full(node_count, -1)
    for k, m in enumerate(members):
        if m.min() < 0 or m.max() >= node_count:
            bad = m.max() if m.max() >= node_count else m.min()
            raise InvalidModelError(
                f"interface {k} refers to node index {bad} of a body with {node_count} nodes",
                item=f"interface {k}",
            )
        shared = m[seen[m] >= 0]
        if shared.size:
            raise InvalidModelError(
                f"interfaces {seen[shared[0]]} and {k} share node index {shared[0]}",
                item=f"interface {k}",
            )
        seen[m] = k
    return members


def _orthonormal_diagonal(
    basis: NDArray[np.float64], k: sp.spmatrix, m: sp.spmatrix
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """M-orthonormalizes a basis (dropping dependent directions) and diagonalizes the reduced
    stiffness: returns the modes and their eigenvalues.

    Each column is first scaled to unit M-norm, so that dependence is judged independently of
    the columns' units: the rotations of a millimetre-sized interface (metres per radian) weigh
    1e-6 of its translations in M and must not read as dependent on them."""
    mb = basis.T @ (m @ basis)
    norms = np.sqrt(np.clip(np.diag(mb), 0.0, None))
    live = norms > 1e-150 * max(norms.max(initial=0.0), 1e-300)
    basis, norms = basis[:, live], norms[live]
    mb = mb[np.ix_(live, live)] / np.outer(norms, norms)
    w, v = np.linalg.eigh(0.5 * (mb + mb.T))
    keep = w > 1e-10 * w.max()
    basis = basis @ ((v[:, keep] / np.sqrt(w[keep])) / norms[:, None])
    kr = basis.T @ (k @ basis)
    values, vectors = np.linalg.eigh(0.5 * (kr + kr.T))
    return basis @ vectors, values


def craig_bampton(
    stiffness: sp.spmatrix,
    mass: sp.spmatrix,
    interfaces: Sequence[ArrayLike | Interface],
    count: int,
    *,
    nodes: NDArray[np.float64],
    elements: Mapping[str, ArrayLike] | None = None,
    weights: str | Sequence[str | ArrayLike] = "auto",
    dofs_per_node: int = 3,
    kind: str = "rbe2",
    reference: str = "mean-axis",
    precision: str = "auto",
    unused: ArrayLike = (),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Craig-Bampton basis over all nodal coordinates: `count` fixed-interface normal modes
    and the static constraint modes of the interfaces (lists of node indices, disjoint, or
    `Interface`s). `unused`: coordinates without stiffness and mass (the rotations of nodes
    of solids alone in a body with beams or shells), left out of the problem and zero in
    the basis.

    `weights` (one for all interfaces, or one per interface; see
    :mod:`flexmbd.fe.interface`, with the body's `elements` for area, length and volume
    weights) weight the averaged motion of "rbe3" interfaces and place the centroids of
    "rbe2" ones.

    `kind`:
      - "nodal": one static mode per coordinate of every interface node (classic
        Craig-Bampton);
      - "rbe2": each interface moves rigidly with its centroid; six static modes per
        interface (u_c, theta_c); the normal modes hold the interface nodes;
      - "rbe3": six static modes per interface that prescribe its weighted averaged motion
        (`Interface.average_rows`) with least strain energy; the interface nodes deform
        freely; the normal modes hold the averaged motions at zero.

    `reference`:
      - "mean-axis": the rigid motions are removed by mass-orthogonalization, so that the
        body frame is a (linearized) mean-axis frame (Tisserand conditions);
      - "interface": the static modes of the first interface are dropped, so that the body
        frame follows the first interface (rigidly attached to its nodes for "nodal" and
        "rbe2", to their averaged motion for "rbe3").

    `precision`: of the factorization ("double", "single", "auto"; see `Inverse`).

    Returns the modes, M-orthonormalized with diagonal modal stiffness, and their
    frequencies (Hz)."""
    if kind not in INTERFACE_KINDS:
        raise InvalidParameterError(
            f"interface kind must be one of {INTERFACE_KINDS}, got {kind!r}"
        )
    if reference not in ("mean-axis", "interface"):
        raise InvalidParameterError(
            f"Craig-Bampton reference must be 'mean-axis' or 'interface', got {reference!r}"
        )
    nodes = np.asarray(nodes, dtype=float)
    d = dofs_per_node
    n = stiffness.shape[0]
    members = _interface_members(interfaces, len(nodes))
    weighted = (
        []
        if kind == "nodal"
        else interface_objects(
            interfaces, nodes, elements, weights, rotation=kind == "rbe3", nodal_rotations=d >= 6
        )
    )
    kept = np.setdiff1d(np.arange(n), np.asarray(unused, dtype=np.int64))
    k = sp.csc_matrix(stiffness)
    m = sp.csc_matrix(mass)
    if len(kept) < n:
        k, m = k[kept][:, kept].tocsc(), m[kept][:, kept].tocsc()
    if kind == "rbe3":
        phi, psi = _craig_bampton_averaged(
            k, m, weighted, count, nodes, d, reference, precision, kept
        )
    else:
        phi, psi = _craig_bampton_fixed(
            k, m, members, weighted, count, nodes, d, reference, precision, kept
        )
    basis = np.hstack([phi, psi])
    if reference == "mean-axis":
        r = rigid_modes(nodes, d)[kept]
        mr = m @ r
        basis = basis - r @ np.linalg.solve(r.T @ mr, mr.T @ basis)
    if basis.shape[1] == 0:
        raise InvalidModelError("the Craig-Bampton basis is empty: ask for modes")
    modes, values = _orthonormal_diagonal(basis, k, m)
    if len(kept) != modes.shape[0]:  # pragma: no cover - internal consistency
        raise AssertionError("basis of the wrong size")
    full = np.zeros((n, modes.shape[1]))
    full[kept] = modes
    return full, frequencies(values)


def _craig_bampton_fixed(
    k: sp.csc_matrix,
    m: sp.csc_matrix,
    members: list[NDArray],
    rigid: list[Interface],
    count: int,
    nodes: NDArray[np.float64],
    d: int,
    reference: str,
    precision: str,
    kept: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Nodal and rigid (RBE2) interfaces: the interface nodes are the boundary coordinates.
    `rigid`: the interfaces (in the order of `members`) of "rbe2", empty for "nodal". `k`
    and `m` hold the nodal coordinates `kept` (see `craig_bampton`), as do the results."""
    n = k.shape[0]
    position = np.full(len(nodes) * d, -1, dtype=np.int64)
    position[kept] = np.arange(n)
    boundary_nodes = np.concatenate(members)
    every = position[(boundary_nodes[:, None] * d + np.arange(d)).ravel()]
    boundary = every[every >= 0]
    interior = np.setdiff1d(np.arange(n), boundary)
    # Columns of the prescribed boundary motions T (n_b, modes), per interface.
    blocks = []
    for index, nodes_of in enumerate(members):
        if reference == "interface" and index == 0:
            continue
        t = rigid[index].rigid_map(d) if rigid else np.eye(len(nodes_of) * d)
        block = np.zeros((len(every), t.shape[1]))
        start = sum(len(members[j]) for j in range(index)) * d
        block[start : start + t.shape[0]] = t
        blocks.append(block)
    t_all = np.hstack(blocks) if blocks else np.zeros((len(every), 0))
    if len(boundary) < len(every):
        # Motions of coordinates left out (the rotations of nodes of solids alone): gone.
        t_all = t_all[every >= 0]
        t_all = t_all[:, np.any(t_all != 0.0, axis=0)]
    # Only the lower triangle of K_ii is formed (the factor keeps it and multiplies by K_ii).
    kii = lower_triangle(k[interior][:, interior])
    scale = _scale(kii, m)
    mii = _Restricted(m, interior) if len(interior) > DENSE_LIMIT else m[interior][:, interior]
    inverse = None
    if len(interior) > DENSE_LIMIT or t_all.shape[1]:
        inverse = Inverse(
            kii,
            single=_use_single(precision, len(interior)),
            dofs=kept[interior],
            nodes=nodes,
            dofs_per_node=d,
            name="interior stiffness K_ii (interfaces held)",
        )
    psi = np.zeros((n, t_all.shape[1]))
    if t_all.shape[1]:
        psi[boundary] = t_all
        psi[interior] = -inverse.solve(np.asarray(k[interior][:, boundary] @ t_all))
    vectors = np.zeros((len(interior), 0))
    if count:
        solve = None
        if inverse is None:
            kii = kii + sp.tril(kii, -1).T
        else:
            # The factor holds K_ii: the copy here is dropped (memory of large bodies).
            solve, kii = inverse.precondition, inverse
        values, vectors = whole_groups(kii, mii, count, "Craig-Bampton normal modes", solve=solve)
        _check_fixed(values, scale, "the interfaces")
    del kii, mii, inverse
    phi = np.zeros((n, count))
    phi[interior] = vectors
    return phi, psi


def _craig_bampton_averaged(
    k: sp.csc_matrix,
    m: sp.csc_matrix,
    interfaces: list[Interface],
    count: int,
    nodes: NDArray[np.float64],
    d: int,
    reference: str,
    precision: str,
    kept: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Averaged (RBE3) interfaces: constraints G u = g with six rows per interface. `k` and
    `m` hold the nodal coordinates `kept` (see `craig_bampton`), as do the results.

    Problems min 1/2 u.K u - f.u subject to G u = g are solved exactly although K is
    singular: with R the rigid motions and S six coordinates that fix a rigid motion, u =
    R a + w with w_S = 0, K_rr w_r = f_r - G_r^T lambda, and a small dense system for
    (lambda, a) from G u = g and R^T (f - G^T lambda) = 0."""
    n = k.shape[0]
    g = sp.vstack([s.average_rows(d, len(nodes) * d) for s in interfaces]).tocsr()
    if n < g.shape[1]:
        left_out = np.setdiff1d(np.arange(g.shape[1]), kept)
        touched = np.flatnonzero(abs(g[:, left_out]).sum(axis=1))
        if len(touched):
            index = int(touched[0]) // 6
            raise InvalidModelError(
                f"averaged interface {index} takes its rotation from the rotations of "
                "nodes of solids alone, which nothing holds (a line of nodes of solids): add "
                "nodes off the line, or nodes of beams or shells, to the interface",
                item=f"interface {index}",
            )
        g = g[:, kept]
    r = rigid_modes(nodes, d)[kept]
    support = _support_dofs(r)
    rest = np.setdiff1d(np.arange(n), support)
    krr = k[rest][:, rest].tocsc()
    inverse = Inverse(
        krr,
        single=_use_single(precision, len(rest)),
        dofs=kept[rest],
        nodes=nodes,
        dofs_per_node=d,
        name="stiffness with a 3-2-1 support",
    )
    g_r = g[:, rest]
    z = inverse.solve(np.asarray(g_r.T.todense()))  # K_rr^-1 G_r^T
    c = np.asarray(g_r @ z)
    gr = np.asarray(g @ r)
    q = g.shape[0]
    # Equilibrated: C ~ 1/stiffness while G R ~ 1; the multipliers are solved as s lambda.
    s = max(np.abs(c).max(), 1e-300)
    small = np.block([[-c / s, gr], [gr.T, np.zeros((6, 6))]])
    small_lu = sla.lu_factor(small)

    def constrained_solve(f: NDArray, rhs_g: NDArray) -> NDArray:
        """u minimizing 1/2 u.K u - f.u subject to G u = rhs_g (columns)."""
        w_f = inverse.solve(f[rest])
        top = rhs_g - g_r @ w_f
        bottom = r.T @ f
        sol = sla.lu_solve(small_lu, np.vstack([top, s * bottom]))
        lam, a = sol[:q] / s, sol[q:]
        u = r @ a
        u[rest] += w_f - z @ lam
        return u

    first = 6 if reference == "interface" else 0
    prescribed = np.eye(q)[:, first:]
    psi = constrained_solve(np.zeros((n, prescribed.shape[1])), prescribed)
    phi = np.zeros((n, 0))
    if count:

        def solve(y: NDArray) -> NDArray:
            y2 = y.reshape(n, -1)
            return constrained_solve(y2, np.zeros((q, y2.shape[1]))).reshape(y.shape)

        dense = None
        if n <= DENSE_LIMIT:
            dense = sla.null_space(g.toarray())
        ggt = np.asarray((g @ g.T).todense())

        def project(r: NDArray) -> NDArray:
            """The Euclidean projection onto G x = 0 (removes G^T mu)."""
            return r - g.T @ np.linalg.solve(ggt, g @ r)

        values, phi = whole_groups(
            k,
            m,
            count,
            "Craig-Bampton normal modes",
            solve=solve,
            dense_projection=dense,
            project=project,
        )
        _check_fixed(values, _scale(k, m), "the averaged interfaces")
    return phi, psi


# Modal invariants --------------------------------------------------------------------------------


def modal_invariants(
    nodal: dict[str, Any],
    modes: NDArray[np.float64],
    scalar_mass: sp.spmatrix | None = None,
) -> dict[str, Any]:
    """Invariants in modal coordinates (seed eq. 18): I1 B, B^T I_kl B, Ibar_kl B; the mass
    and the moments of the undeformed body are unchanged. For solids, `scalar_mass` (M_s with
    I_kl = M_s (x) e_k e_l^T) gives B^T I_kl B = B_k^T M_s B_l from three products."""
    b = modes
    if scalar_mass is not None:
        parts = [b[c::3] for c in range(3)]
        ms_parts = [scalar_mass @ p for p in parts]
        i_kl = [[np.asarray(parts[kk].T @ ms_parts[ll]) for ll in range(3)] for kk in range(3)]
    else:
        i_kl = [
            [np.asarray(b.T @ (nodal["i_kl"][kk][ll] @ b)) for ll in range(3)] for kk in range(3)
        ]
    return {
        "mass": nodal["mass"],
        "first_moment": nodal["first_moment"],
        "second_moment": nodal["second_moment"],
        "i1": nodal["i1"] @ b,
        "ibar": np.einsum("kln,nm->klm", nodal["ibar"], b),
        "i_kl": i_kl,
    }
