"""Low-discrepancy points: a Halton sequence with random digit permutations (scrambled per seed),
so every frame's light paths are stratified and different frames' sets are independent."""

from __future__ import annotations

import numpy as np

DIGIT_BITS = 32  # precision of each coordinate, in bits


def primes(count: int) -> np.ndarray:
    """The first ``count`` prime numbers."""
    limit = max(16, int(count * (np.log(count + 2) + np.log(np.log(count + 2))) + 10))
    sieve = np.ones(limit + 1, dtype=bool)
    sieve[:2] = False
    for p in range(2, int(limit**0.5) + 1):
        if sieve[p]:
            sieve[p * p::p] = False
    return np.flatnonzero(sieve)[:count]


def radical_inverse(index: int, base: int) -> float:
    """The index's digits in ``base`` mirrored behind the point (van der Corput; unscrambled,
    so the same in every process)."""
    value, scale = 0.0, 1.0 / base
    while index:
        index, digit = divmod(index, base)
        value += digit * scale
        scale /= base
    return value


def scrambled_halton(count: int, dimensions: int, seed: int, first: int = 0) -> np.ndarray:
    """``count`` points in [0, 1)^dimensions, the sequence's from index ``first``: dimension k
    is the radical inverse in the k-th prime base with an independent random permutation of
    the digits at every digit position (the same for every ``first``: consecutive ranges
    continue one sequence)."""
    rng = np.random.default_rng(seed)
    index = np.arange(first, first + count, dtype=np.int64)
    points = np.empty((count, dimensions))
    for k, base in enumerate(primes(dimensions)):
        digits = int(np.ceil(DIGIT_BITS / np.log2(base)))
        value = np.zeros(count)
        scale = 1.0 / base
        remaining = index.copy()
        for _ in range(digits):
            permutation = rng.permutation(base)
            value += permutation[remaining % base] * scale
            remaining //= base
            scale /= base
        points[:, k] = value
    return np.minimum(points, np.nextafter(1.0, 0.0))
