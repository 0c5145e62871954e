"""Rotation helpers: rotation matrices from an axis and angle, and from Euler parameters, and
angular velocities from Euler parameter rates."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rotation(axis: ArrayLike | str, angle: float) -> NDArray[np.float64]:
    """Rotation matrix for a rotation by ``angle`` (rad) about ``axis`` (a 3-vector, or
    ``"x"``, ``"y"``, ``"z"``), by Rodrigues' formula."""
    if isinstance(axis, str):
        index = {"x": 0, "y": 1, "z": 2}.get(axis.lower())
        if index is None:
            raise ValueError(f"axis must be 'x', 'y', 'z' or a 3-vector, got {axis!r}")
        a = np.zeros(3)
        a[index] = 1.0
    else:
        a = np.asarray(axis, dtype=float).reshape(3)
        norm = np.linalg.norm(a)
        if not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"axis must be a non-zero finite 3-vector, got {axis!r}")
        a = a / norm
    k = skew(a)
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """The cross-product matrix of the 3-vector `v`: skew(v) @ w = v x w."""
    a = np.asarray(v, dtype=float)
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def euler_parameters_to_matrix(p: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices from Euler parameters [e0, e1, e2, e3] (shape (..., 4) -> (..., 3, 3))."""
    p = np.asarray(p, dtype=float)
    e0, e1, e2, e3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    a = np.empty(p.shape[:-1] + (3, 3))
    a[..., 0, 0] = e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3
    a[..., 0, 1] = 2.0 * (e1 * e2 - e0 * e3)
    a[..., 0, 2] = 2.0 * (e1 * e3 + e0 * e2)
    a[..., 1, 0] = 2.0 * (e1 * e2 + e0 * e3)
    a[..., 1, 1] = e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3
    a[..., 1, 2] = 2.0 * (e2 * e3 - e0 * e1)
    a[..., 2, 0] = 2.0 * (e1 * e3 - e0 * e2)
    a[..., 2, 1] = 2.0 * (e2 * e3 + e0 * e1)
    a[..., 2, 2] = e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3
    return a


def angular_velocity(p: ArrayLike, p_dot: ArrayLike, frame: str = "global") -> NDArray[np.generic]:
    """Angular velocity from Euler parameters p = [e0, e] and their rates (shapes (..., 4) ->
    (..., 3)): omega = 2 E(p) p_dot = 2 (-e e0_dot + e0 e_dot + e x e_dot) in global axes
    (`frame` "global"), 2 G(p) p_dot = 2 (-e e0_dot + e0 e_dot - e x e_dot) in body axes
    ("body"). Rates may be complex (a mode shape's). A change dp of the parameters turns the
    frame by the small rotation of the same formula."""
    p = np.asarray(p)
    p_dot = np.asarray(p_dot)
    e0, e = p[..., :1], p[..., 1:]
    e0_dot, e_dot = p_dot[..., :1], p_dot[..., 1:]
    sign = {"global": 1.0, "body": -1.0}[frame]
    return 2.0 * (-e * e0_dot + e0 * e_dot + sign * np.cross(e, e_dot))


def euler_parameter_rates(
    p: ArrayLike, omega: ArrayLike, frame: str = "global"
) -> NDArray[np.float64]:
    """Rates of Euler parameters p = [e0, e] for the angular velocity omega (shapes (4,),
    (3,) -> (4,)), the inverse of :func:`angular_velocity` for unit p: 1/2 E(p)^T omega =
    1/2 [-e.omega, e0 omega - e x omega] for omega in global axes (`frame` "global"),
    1/2 G(p)^T omega = 1/2 [-e.omega, e0 omega + e x omega] in body axes ("body"). With p's
    rates for p (and omega held) it is the part of p's second rates that omega's own rate
    leaves out."""
    p = np.asarray(p, dtype=float)
    omega = np.asarray(omega, dtype=float)
    e0, e = p[0], p[1:]
    sign = {"global": -1.0, "body": 1.0}[frame]
    return 0.5 * np.concatenate([[-e @ omega], e0 * omega + sign * np.cross(e, omega)])
