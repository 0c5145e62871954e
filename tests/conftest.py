"""Shared helpers of the Python tests."""

from __future__ import annotations

import numpy as np


def relative_drift(energy: np.ndarray) -> float:
    """Largest |E(t) - E(0)| / |E(0)| over a run."""
    return float(np.max(np.abs(energy - energy[0])) / abs(energy[0]))


def rod_inertia(mass: float, length: float, axial: float = 1e-6) -> tuple[float, float, float]:
    """Principal inertia of a slender rod along its local x axis about its centre."""
    transverse = mass * length**2 / 12.0
    return (axial, transverse, transverse)
