"""Plausible cameras drawn from the prior over measured ones, for camera-agnostic training
(``sensor=random``, issue 35): ``random:<seed>`` names one draw, the same curves every time."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from illumix.sensor_estimate.prior import Prior, learn_prior, load_measured, normalised

#: draws beyond this many standard deviations per component are pulled back to it: the Gaussian's
#: tails are not cameras anyone measured
MAX_SIGMA = 2.0


@lru_cache(maxsize=4)
def measured_prior(folders: tuple[str, ...], grid) -> Prior:
    """The prior of the measured cameras in ``folders`` (learned once per folder set and grid)."""
    return learn_prior(load_measured(list(folders), grid))


def draw_camera(prior: Prior, seed: int) -> np.ndarray:
    """``(n_bands, 3)`` curves (non-negative, green sums to 1) of the camera drawn with ``seed``."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xCA3E7A])
    z = np.clip(rng.standard_normal(len(prior.variance)), -MAX_SIGMA, MAX_SIGMA)
    return normalised(np.maximum(prior.curves(z * np.sqrt(prior.variance)), 0.0))
