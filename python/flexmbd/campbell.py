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
sorting: a curve keeps its mode through a crossing with another. The frequencies are those
seen in the frame of the rotating bodies (the floating frames turn with the rotor).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._checks import integer, numbers_array
from .errors import InvalidParameterError

Array = NDArray[np.float64]

#: Candidate modes per speed beyond those followed (a followed mode may rise above the others).
EXTRA_CANDIDATES = 6


@dataclass
class CampbellDiagram:
    """The modes of a rotor against its speed: `speeds` (rad/s), and per speed and followed
    mode the damped `frequencies` (Hz), `damping` ratios and complex `shapes` (in the
    coordinates q of the model), and the MAC with which each mode was matched to the speed
    before (`mac`, 1 at the first speed)."""

    speeds: Array
    frequencies: Array
    damping: Array
    shapes: NDArray[np.complex128] = field(repr=False)
    mac: Array = field(repr=False)
    driver: str = ""

    @property
    def mode_count(self) -> int:
        return self.frequencies.shape[1]

    def critical_speeds(self, orders: Any = (1, 2, 3)) -> list[dict[str, float]]:
        """Where an excitation order meets a mode: the speeds W (rad/s) at which a mode's
        frequency f(W) equals k W / (2 pi) for the orders k, interpolated linearly between
        the speeds computed; a list of dicts with order, mode, speed and frequency (Hz),
        by speed."""
        found = []
        w = self.speeds
        for k in np.atleast_1d(np.asarray(orders, dtype=float)):
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
                        }
                    )
        return sorted(found, key=lambda c: c["speed"])

    def to_xarray(self) -> Any:
        """The diagram as an xarray Dataset over speed (rad/s) and mode: frequency (Hz),
        damping ratio and MAC."""
        import xarray as xr

        coords = {"speed": self.speeds, "mode": np.arange(self.mode_count)}
        data = xr.Dataset(
            {
                "frequency": (("speed", "mode"), self.frequencies),
                "damping_ratio": (("speed", "mode"), self.damping),
                "mac": (("speed", "mode"), self.mac),
            },
            coords=coords,
        )
        data["frequency"].attrs["units"] = "Hz"
        data["speed"].attrs["units"] = "rad/s"
        data.attrs["driver"] = self.driver
        return data


def _mac(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> Array:
    """MAC of every column of `a` with every column of `b`."""
    cross = np.abs(a.conj().T @ b) ** 2
    norms = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    return cross / np.where(norms > 0.0, norms, 1.0)


def campbell(
    system: Any,
    driver: str,
    speeds: Any,
    *,
    modes: int = 6,
    time: float = 0.0,
    gyroscopic: bool = True,
) -> CampbellDiagram:
    """The Campbell diagram of `system` (a :class:`flexmbd.System`) turned by its angle
    driver `driver` at each of `speeds` (rad/s, ascending): the `modes` lowest oscillating
    modes at the first speed, followed across the speeds by their shapes (see the module).
    At each speed the driver's angle is theta(time) + W (t - time), the state the steady
    rotation at `time`. `gyroscopic=False` leaves the velocity-dependent terms (Coriolis
    coupling, gyroscopic moments, damping) out of the eigenvalue problem."""
    from .analysis import equilibrium, linearize, steady_rotation
    from .system import System

    if not isinstance(system, System):
        raise InvalidParameterError(
            "campbell needs a flexmbd.System (it builds the system again at every speed)",
            item="system",
        )
    speeds = numbers_array(speeds, "speeds").ravel()
    count = integer(modes, "modes")
    if count < 1:
        raise InvalidParameterError(f"modes must be at least 1, got {count}", item="modes")
    if not np.all(np.isfinite(speeds)):
        raise InvalidParameterError("speeds must be finite", item="speeds")
    if len(speeds) == 0 or np.any(np.diff(speeds) <= 0):
        raise InvalidParameterError("speeds must be ascending and not empty", item="speeds")
    start = float(system.driver_function(driver)(time))
    from ._boundary import Polynomial

    frequencies, damping, shapes, mac = [], [], [], []
    followed = None
    for w in speeds:
        turning = system.with_driver(driver, Polynomial([start - w * time, float(w)]))
        model = turning.compile()
        state = steady_rotation(model, time) if w != 0.0 else equilibrium(model, time)
        linear = linearize(model, state)
        if not gyroscopic:
            linear = linear.without_velocity_terms()
        f, zeta, phi = (part[..., : count + EXTRA_CANDIDATES] for part in linear.oscillating())
        if followed is None:
            if len(f) < count:
                raise InvalidParameterError(
                    f"campbell: the model has {len(f)} oscillating modes at {w:g} rad/s, "
                    f"{count} asked for",
                    item="modes",
                )
            pick = np.arange(count)
            match = np.ones(count)
        else:
            from scipy.optimize import linear_sum_assignment

            table = _mac(followed, phi)
            rows, pick = linear_sum_assignment(-table)
            pick = pick[np.argsort(rows)]
            match = table[np.arange(count), pick]
        followed = phi[:, pick]
        frequencies.append(f[pick])
        damping.append(zeta[pick])
        shapes.append(followed)
        mac.append(match)
    return CampbellDiagram(
        speeds=speeds,
        frequencies=np.array(frequencies),
        damping=np.array(damping),
        shapes=np.array(shapes),
        mac=np.array(mac),
        driver=driver,
    )


def plot_campbell(
    diagram: CampbellDiagram,
    path: str | os.PathLike[str] | None = None,
    *,
    orders: Any = (1, 2, 3),
    ax: Any = None,
) -> Any:
    """Draws the Campbell diagram: each followed mode's frequency (Hz) against the speed
    (rad/s), the excitation-order lines k W / (2 pi) and their crossings with the modes
    (critical speeds, circled). Saves to `path` if given; returns the Axes."""
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 5))
    w = diagram.speeds
    for m in range(diagram.mode_count):
        ax.plot(w, diagram.frequencies[:, m], "-", lw=1.5, label=f"mode {m + 1}")
    top = float(np.max(diagram.frequencies)) * 1.05
    for k in np.atleast_1d(orders):
        ax.plot(w, k * w / (2 * np.pi), "k--", lw=0.8)
        ax.annotate(f"{k:g}x", (w[-1], min(k * w[-1] / (2 * np.pi), top)), fontsize=8)
    for c in diagram.critical_speeds(orders):
        ax.plot(c["speed"], c["frequency"], "o", mfc="none", mec="r", ms=8)
    ax.set_ylim(0.0, top)
    ax.set_xlabel("speed (rad/s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(f"Campbell diagram (driver {diagram.driver!r})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    if path is not None:
        (fig or ax.figure).tight_layout()
        (fig or ax.figure).savefig(path)
        if fig is not None:
            plt.close(fig)
    return ax
