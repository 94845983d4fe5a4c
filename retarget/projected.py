"""A group's camera raw, already projected: the cube's product with one set of band weights.

Relight + projection is linear in the weights: ``T @ (s · M) = s · (T @ M)``. A window of ``T @ M``
computed once (for a sensor and illuminant at intensity 1) therefore serves every later request
with the same sensor and illuminant at any intensity ``s`` by one scalar product, exactly, instead
of a 63-band product per pixel. :func:`retarget.basis.project_groups_any` accepts a
:class:`Projected` in place of a cube and checks that the request's weights are a multiple of the
ones it was computed with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError

# Weights of one sensor and illuminant at two intensities differ by a float64 scalar multiple up
# to rounding of that multiplication (~1e-16); anything beyond 1e-9 is a different request.
_PARALLEL_RTOL = 1e-9
# The largest magnitude float32 rounds to zero (half its smallest subnormal 2^-149, ties to even).
_F32_ZERO = 2.0 ** -150


@dataclass(frozen=True)
class Projected:
    """``raw`` ``(H, W, 3)`` float32 = ``cube @ weights`` for ``weights`` ``(B, 3)``."""

    raw: np.ndarray
    weights: np.ndarray
    n_bands: int

    @property
    def shape(self) -> tuple[int, int, int]:
        return (*self.raw.shape[:2], self.n_bands)

    def project(self, weights: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``cube @ weights`` ``(H, W, 3)`` for ``weights`` parallel to :attr:`weights` (into ``out``
        when given); zeros for weights that vanish in float32 (the cube path's precision)."""
        ref = np.asarray(self.weights, np.float64)
        w = np.asarray(weights, np.float64)
        if float(np.abs(w).max(initial=0)) <= _F32_ZERO:
            # Weights below float32's smallest subnormal (e.g. intensity 1e-320): the cube path
            # multiplies in float32, where they are all zero, so the exact answer is a dark frame
            # whatever their direction. They cannot be checked either: a float64 subnormal keeps
            # only a few bits, so ``a · Φ/E · C`` is no longer a multiple of the unit weights to
            # 1e-9 (that rounding, not a cache-key bug, is what the check used to report).
            s = 0.0
        else:
            norm = float(np.abs(ref).sum())
            s = float(np.abs(w).sum()) / norm if norm > 0 else 0.0
            if float(np.abs(w - s * ref).max(initial=0)) > _PARALLEL_RTOL * float(np.abs(w).max(initial=0)):
                raise SpectralError("project: a cached projection was asked for different band weights "
                                    "(another sensor or illuminant); this is a bug in its cache key")
        if out is None:
            return self.raw if s == 1.0 else self.raw * np.float32(s)
        return np.multiply(self.raw, np.float32(s), out=out)

    def window(self, x: int, y: int, w: int, h: int) -> Projected:
        return Projected(self.raw[y:y + h, x:x + w], self.weights, self.n_bands)
