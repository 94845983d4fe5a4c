"""The base-colour scale ``c`` that maps Mitsuba's ``roughplastic`` to Blender's Principled BSDF
(the Cycles backend, :mod:`renderer_jobs.cycles_job`) and back (the importers of Blender, glTF and
OBJ materials): Mitsuba darkens its diffuse term by the rough coating's transmittances,
``ρ t(θ_i) t(θ_o) / (η² (1 − F_int))``, which the Principled BSDF does not.

:func:`plastic_diffuse_scale` reads a table (:mod:`renderer_jobs.plastic_scale_table`) fitted once
with Mitsuba (:func:`fit_scale`), so an imported scene is the same whether or not Mitsuba is
installed (it once fell back to the smooth-interface value without it: 1.06 instead of 0.73 at
α = 0.25, η = 1.5, an import 45 % darker). ``python -m illumix.renderer_jobs.plastic_scale`` writes the
table again (Mitsuba needed).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np


def _fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
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
    return float(np.sum(_fresnel(mu, eta) * 2 * mu) / n)


@functools.lru_cache(maxsize=256)
def plastic_diffuse_scale(alpha: float, eta: float) -> float:
    """``c`` at GGX roughness ``alpha`` and relative IOR ``eta``: bilinear in ``(log α, η)`` on the
    table of :func:`fit_scale` (within 0.3 % of it on average, 1.5 % at the worst, α < 0.003, where
    Mitsuba's own transmittance tables are bumpy in η); outside the table's range (α 0.001–1,
    η 1.05–3) the nearest edge. 0.73 at α = 0.25, η = 1.5; 0.93 at α = 0.08."""
    from illumix.renderer_jobs.plastic_scale_table import ALPHAS, ETAS, SCALE

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


def fit_scale(alpha: float, eta: float, n: int = 48) -> float:
    """The base-colour scale ``c`` of the roughplastic mapping: Cycles' diffuse lobe, modelled as
    ``c ρ (1 − F(θ_o)) cosθ_o / π``, fitted to Mitsuba's own diffuse term
    ``ρ t(θ_i) t(θ_o) cosθ_o / (η² (1 − F_int) π)`` (rough transmittance tables; measured by
    evaluating Mitsuba's ``roughplastic`` at ρ = 1 and 0) in the least-squares sense over incident and
    outgoing directions, both cosine-weighted (``n`` cosines each). Needs Mitsuba: it writes the
    table that :func:`plastic_diffuse_scale` reads."""
    from illumix.renderer_jobs.mitsuba_variant import import_mitsuba, select_variant

    select_variant()
    mi, dr = import_mitsuba()
    mu = (np.arange(n) + 0.5) / n
    ci, co = (a.ravel() for a in np.meshgrid(mu, mu, indexing="ij"))
    vals = []
    for rho in (1.0, 0.0):
        b = mi.load_dict({"type": "roughplastic", "alpha": alpha, "int_ior": eta, "ext_ior": 1.0,
                          "distribution": "ggx", "diffuse_reflectance": {"type": "uniform", "value": rho}})
        si = dr.zeros(mi.SurfaceInteraction3f, len(ci))
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        if "spectral" in mi.variant():
            si.wavelengths = mi.Spectrum(550.0, 550.0, 550.0, 550.0)
        si.wi = mi.Vector3f(mi.Float(np.sqrt(1 - ci ** 2)), 0, mi.Float(ci))
        wo = mi.Vector3f(mi.Float(-np.sqrt(1 - co ** 2)), 0, mi.Float(co))
        vals.append(np.asarray(b.eval(mi.BSDFContext(), si, wo))[0])
    mitsuba = (vals[0] - vals[1]) * np.pi / co  # Mitsuba's diffuse factor on ρ
    cycles = 1 - _fresnel(co, eta)
    w = ci * co
    return float(np.sum(w * mitsuba * cycles) / np.sum(w * cycles ** 2))


def write_table(path: Path | None = None) -> Path:
    """Fit :func:`fit_scale` on the grid (25 roughnesses log-spaced over 0.001–1, IOR 1.05–3 in steps
    of 0.05) and write :mod:`renderer_jobs.plastic_scale_table`."""
    import textwrap

    alphas = np.round(np.geomspace(0.001, 1, 25), 5)
    etas = np.round(np.arange(1.05, 3.0001, 0.05), 3)
    rows = []
    for a in alphas:
        vals = [f"{fit_scale(float(a), float(e)):.5f}" for e in etas]
        rows.append("    (" + ",\n     ".join(", ".join(vals[k:k + 10]) for k in range(0, len(vals), 10)) + "),")

    def wrapped(name: str, values) -> str:
        return f"{name} = (\n" + "\n".join("    " + s for s in textwrap.wrap(", ".join(f"{v:g}" for v in values), 100)) + "\n)"

    path = path or Path(__file__).with_name("plastic_scale_table.py")
    head = ('"""Table of :func:`renderer_jobs.plastic_scale.fit_scale` (Mitsuba\'s roughplastic): written by\n'
            "``python -m illumix.renderer_jobs.plastic_scale``, checked against Mitsuba by ``tests/test_plastic_scale.py``.\n"
            'Rows: ``ALPHAS`` (GGX α, log-spaced); columns: ``ETAS`` (interior / exterior IOR)."""\n\n')
    path.write_text(head + wrapped("ALPHAS", alphas) + "\n" + wrapped("ETAS", etas) + "\nSCALE = (\n" + "\n".join(rows)
                    + "\n)\n")
    return path


if __name__ == "__main__":
    print(write_table())
