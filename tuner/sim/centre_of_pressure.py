"""Centre of pressure of point forces: the measured ZMP of a sole with force sensors."""

from __future__ import annotations

import numpy as np

__all__ = ["centre_of_pressure"]


def centre_of_pressure(force: np.ndarray, position: np.ndarray, min_total: float = 0.0) -> np.ndarray:
    """CoP (K, 2) of K samples of N point forces (K, N) at positions (K, N, 2 or 3); NaN if unloaded."""
    force = np.asarray(force, dtype=float)
    position = np.asarray(position, dtype=float)
    if force.ndim != 2 or position.shape[:2] != force.shape:
        raise ValueError(f"forces (K, N) and positions (K, N, 2|3) must agree, got {force.shape} "
                         f"and {position.shape}")
    total = force.sum(axis=1)
    out = np.full((len(force), 2), np.nan)
    ok = total > max(min_total, 0.0)
    out[ok] = np.einsum("kn,knj->kj", force[ok], position[ok, :, :2]) / total[ok, None]
    return out
