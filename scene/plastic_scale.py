"""The base-colour scale ``c`` that maps Mitsuba's ``roughplastic`` to Blender's Principled BSDF
(the Cycles backend, :mod:`renderer_jobs.cycles.job`) and back (the importers of Blender, glTF and
OBJ materials): Mitsuba darkens its diffuse term by the rough coating's transmittances,
``ρ t(θ_i) t(θ_o) / (η² (1 − F_int))``, which the Principled BSDF does not.

:func:`plastic_diffuse_scale` reads a table (:mod:`scene.plastic_scale_table`) fitted once
with Mitsuba (:func:`renderer_jobs.mitsuba.plastic_fit.fit_scale`), so an imported scene is the same
whether or not Mitsuba is installed (it once fell back to the smooth-interface value without it: 1.06 instead of 0.73 at
α = 0.25, η = 1.5, an import 45 % darker). ``python -m illumix.renderer_jobs.mitsuba.plastic_fit`` writes
the table again (Mitsuba needed).
"""

from __future__ import annotations

import functools
import numpy as np


def fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a smooth dielectric interface (relative IOR ``eta``)."""
    sin_t2 = (1 - cos_i ** 2) / eta ** 2
    cos_t = np.sqrt(np.clip(1 - sin_t2, 0, None))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin_t2 >= 1, 1.0, (rs ** 2 + rp ** 2) / 2)


def diffuse_fresnel(eta: float, n: int = 200_000) -> float:
    """Cosine-weighted hemispherical average ``∫ F(θ) 2 cosθ sinθ dθ`` (Mitsuba's
    ``fresnel_diffuse_reflectance``); ``eta < 1`` from inside (total internal reflection included)."""
    mu = (np.arange(n) + 0.5) / n  # cos θ; 2 cosθ sinθ dθ = d(cos²θ)
    return float(np.sum(fresnel(mu, eta) * 2 * mu) / n)


@functools.lru_cache(maxsize=256)
def plastic_diffuse_scale(alpha: float, eta: float) -> float:
    """``c`` at GGX roughness ``alpha`` and relative IOR ``eta``: bilinear in ``(log α, η)`` on the
    table of :func:`renderer_jobs.mitsuba.plastic_fit.fit_scale` (within 0.3 % of it on average,
    1.5 % at the worst, α < 0.003, where Mitsuba's own transmittance tables are bumpy in η);
    outside the table's range (α 0.001–1, η 1.05–3) the nearest edge. 0.73 at α = 0.25, η = 1.5; 0.93 at α = 0.08."""
    from illumix.scene.plastic_scale_table import ALPHAS, ETAS, SCALE

    la = np.log(np.asarray(ALPHAS))
    etas = np.asarray(ETAS)
    table = np.asarray(SCALE)
    x = float(np.clip(np.log(max(alpha, 1e-12)), la[0], la[-1]))
    y = float(np.clip(eta, etas[0], etas[-1]))
    i = int(np.clip(np.searchsorted(la, x) - 1, 0, la.size - 2))
    j = int(np.clip(np.searchsorted(etas, y) - 1, 0, etas.size - 2))
    tx = (x - la[i]) / (la[i + 1] - la[i])
    ty = (y - etas[j]) / (etas[j + 1] - etas[j])
    return float((1 - tx) * (1 - ty) * table[i, j] + tx * (1 - ty) * table[i + 1, j]
                 + (1 - tx) * ty * table[i, j + 1] + tx * ty * table[i + 1, j + 1])
