"""Random directions and lights for the SH tests (tests/runtime/light/test_sh.py, test_envmap.py, test_lightfile.py).

Seeded, so a failure repeats; ``RNG_SEED`` is the seed they share unless a test asks for another.
"""

from __future__ import annotations

import numpy as np

RNG_SEED = 1234


def random_dirs(n: int, seed: int = RNG_SEED) -> np.ndarray:
    """(n, 3) float64 unit vectors, uniform on the sphere."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_light(seed: int = RNG_SEED, batch: tuple = ()) -> np.ndarray:
    """(*batch, 9, 3) float64 SH coefficients, standard normal."""
    return np.random.default_rng(seed).normal(size=batch + (9, 3))
