"""How long a step the explicit Runge-Kutta methods can take on a model: their regions of
absolute stability against the stiffest elastic modes of its deformable bodies.

An explicit method multiplies each mode's error by its stability function R(h lambda) in a
step, so a mode with eigenvalue lambda limits the step to the boundary of |R| <= 1 along
lambda's direction, whatever the accuracy asked for. The stiffest modes of a deformable body
(an element's axial vibration, or the same mode overdamped by stiffness-proportional damping,
lambda of about -beta omega^2) hold Runge-Kutta 4 and Dormand-Prince to microseconds: a run
of seconds takes millions of steps (Dormand-Prince's error control finds the limit) or, at a
fixed step above it, diverges (Runge-Kutta 4). :func:`explicit_step_limit` predicts the limit
before the run, for the warning of :func:`flexmbd.simulate`; generalized-alpha and TR-BDF2
have no such limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Coefficients of the stability polynomials R(z) = sum c_k z^k of the explicit methods:
#: Runge-Kutta 4, and Dormand-Prince 5(4) (its fifth-order solution, with which it steps:
#: z^6 / 600 from its seven stages).
STABILITY_POLYNOMIALS = {
    "rk4": [1.0 / math.factorial(k) for k in range(5)],
    "dopri5": [1.0 / math.factorial(k) for k in range(6)] + [1.0 / 600.0],
}


def stability_boundary(method: str, direction: complex) -> float:
    """The largest t with |R(t direction)| <= 1 along the unit complex `direction` (within
    1e-6, scanned outward from 0): R of `method` in :data:`STABILITY_POLYNOMIALS`. Along the
    negative real axis 2.785 (rk4) and 3.307 (dopri5); along the imaginary axis 2.828 (rk4)
    and about 1 (dopri5, whose region leaves the axis there)."""
    coefficients = STABILITY_POLYNOMIALS[method][::-1]
    steps = np.linspace(1e-3, 8.0, 8000)
    values = np.abs(np.polyval(coefficients, steps * direction))
    outside = np.flatnonzero(values > 1.0 + 1e-6)
    return float(steps[outside[0] - 1]) if len(outside) and outside[0] > 0 else float(steps[-1])


@dataclass(frozen=True)
class StepLimit:
    """The stability limit of an explicit method on a model: the largest stable `step` (s),
    set by the stiffest mode of body `body`, of eigenvalue `eigenvalue` (1/s; its
    undamped circular frequency `frequency`, rad/s)."""

    step: float
    body: str
    eigenvalue: complex
    frequency: float


def explicit_step_limit(model: Any, method: str) -> StepLimit | None:
    """The stability limit of explicit `method` (``"rk4"`` or ``"dopri5"``) set by the
    stiffest elastic mode of the deformable bodies of compiled `model` at its initial state
    (None without deformable bodies). Per body: the largest eigenvalue omega^2 of its elastic
    stiffness and mass blocks of the Newton matrix, its mode phi's damping
    d = phi^T D phi / phi^T M phi, the root of lambda^2 + d lambda + omega^2 = 0 of largest
    magnitude, and the step that puts h lambda on the method's stability boundary."""
    from .analysis import _matrix

    layout = model.describe()
    bodies = [
        b for k, b in enumerate(layout["bodies"]) if k in model.flexible_bodies and b["count"] > 7
    ]
    if not bodies:
        return None
    q = np.asarray(model.initial_coordinates, dtype=float)
    zero_q, zero_l = np.zeros_like(q), np.zeros(model.constraint_count)

    def matrix(**coefficient: float) -> Any:
        return _matrix(model.evaluate(0.0, q, zero_q, zero_q, zero_l, **coefficient)).tocsr()

    stiffness, damping, mass = matrix(position=1.0), matrix(velocity=1.0), matrix(mass=1.0)
    limit = None
    for body in bodies:
        columns = np.arange(body["offset"] + 7, body["offset"] + body["count"])
        k = stiffness[columns][:, columns]
        m = mass[columns][:, columns]
        omega2, mode = _largest_mode((k + k.T) * 0.5, (m + m.T) * 0.5)
        if not omega2 > 0.0:
            continue
        d = float(mode @ (damping[columns][:, columns] @ mode)) / float(mode @ (m @ mode))
        roots = np.roots([1.0, d, omega2])
        eigenvalue = complex(roots[np.argmax(np.abs(roots))])
        size = abs(eigenvalue)
        step = stability_boundary(method, eigenvalue / size) / size
        if limit is None or step < limit.step:
            limit = StepLimit(step, body["name"], eigenvalue, math.sqrt(omega2))
    return limit


def _largest_mode(k: Any, m: Any) -> tuple[float, np.ndarray]:
    """The largest eigenvalue of K phi = omega^2 M phi and its mode (dense for small blocks,
    Lanczos otherwise)."""
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla

    n = k.shape[0]
    if n <= 300:
        values, vectors = sla.eigh(k.toarray(), m.toarray(), subset_by_index=[n - 1, n - 1])
    else:
        values, vectors = spla.eigsh(k.tocsc(), k=1, M=m.tocsc(), which="LA", tol=1e-4)
    return float(values[-1]), vectors[:, -1]
