"""Image error metrics against a reference (float32 linear images, any channel count)."""

from __future__ import annotations

import numpy as np


def _rgb(image: np.ndarray) -> np.ndarray:
    return np.asarray(image, dtype=np.float64)[..., :3]


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root mean squared error over pixels and colour channels."""
    return float(np.sqrt(np.mean((_rgb(image) - _rgb(reference)) ** 2)))


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """RMSE divided by the reference's mean value: a scale-free per-pixel error."""
    return rmse(image, reference) / max(float(_rgb(reference).mean()), 1e-30)


def relative_mse(image: np.ndarray, reference: np.ndarray, epsilon: float = 1e-2) -> float:
    """Mean of (x - r)² / (r² + ε), per channel (the rendering literature's relMSE)."""
    x, r = _rgb(image), _rgb(reference)
    return float(np.mean((x - r) ** 2 / (r**2 + epsilon)))


def mean_relative_energy(image: np.ndarray, reference: np.ndarray) -> float:
    """(sum x - sum r) / sum r: signed error of the total energy, e.g. -0.05 = 5 % too dark."""
    r = _rgb(reference).sum()
    return float((_rgb(image).sum() - r) / max(r, 1e-30))


def unbiased_squared_error(image: np.ndarray, reference_a: np.ndarray,
                           reference_b: np.ndarray) -> float:
    """mean((x - r1)(x - r2)) with two independently seeded references: an estimate of the
    squared error against the converged image, free of the references' own noise."""
    x = _rgb(image)
    return float(np.mean((x - _rgb(reference_a)) * (x - _rgb(reference_b))))


def reference_noise(reference_a: np.ndarray, reference_b: np.ndarray) -> float:
    """RMS noise of one reference, from the difference of two independent ones."""
    return float(np.sqrt(np.mean((_rgb(reference_a) - _rgb(reference_b)) ** 2) / 2.0))
