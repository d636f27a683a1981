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


def unbiased_squared_error_spread(image: np.ndarray, reference_a: np.ndarray,
                                  reference_b: np.ndarray) -> float:
    """Standard deviation of :func:`unbiased_squared_error` from the references' noise, for a
    fixed image: with x - r_i = e - n_i, each term e² - e(n1 + n2) + n1·n2 varies by
    2e²σ² + σ⁴ (σ² estimated per value as (r1 - r2)² / 2, e² as the term itself, σ⁴ as a third
    of (r1 - r2)⁴ / 4: Gaussian moments). A pixel's channels count as fully correlated (as the
    same light paths make them), which errs on the large side."""
    x, a, b = _rgb(image), _rgb(reference_a), _rgb(reference_b)
    sigma2 = (a - b) ** 2 / 2
    term = np.maximum((x - a) * (x - b), 0.0)
    pixel_sd = np.sqrt(2 * term * sigma2 + sigma2**2 / 3).mean(axis=-1)
    return float(np.sqrt(np.sum(pixel_sd**2)) / pixel_sd.size)
