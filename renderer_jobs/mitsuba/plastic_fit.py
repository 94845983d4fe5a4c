"""Fit the roughplastic base-colour scale with Mitsuba and write the table
:func:`scene.plastic_scale.plastic_diffuse_scale` reads (:mod:`scene.plastic_scale_table`):
``python -m illumix.renderer_jobs.mitsuba.plastic_fit``. The Mitsuba side of the scale; the scene
side reads the table alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from illumix.scene.plastic_scale import fresnel


def fit_scale(alpha: float, eta: float, n: int = 48) -> float:
    """The base-colour scale ``c`` of the roughplastic mapping: Cycles' diffuse lobe, modelled as
    ``c ρ (1 − F(θ_o)) cosθ_o / π``, fitted to Mitsuba's own diffuse term
    ``ρ t(θ_i) t(θ_o) cosθ_o / (η² (1 − F_int) π)`` (rough transmittance tables; measured by
    evaluating Mitsuba's ``roughplastic`` at ρ = 1 and 0) in the least-squares sense over incident and
    outgoing directions, both cosine-weighted (``n`` cosines each). Needs Mitsuba: it writes the
    table that :func:`plastic_diffuse_scale` reads."""
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba, select_variant

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
    cycles = 1 - fresnel(co, eta)
    w = ci * co
    return float(np.sum(w * mitsuba * cycles) / np.sum(w * cycles ** 2))


def write_table(path: Path | None = None) -> Path:
    """Fit :func:`fit_scale` on the grid (25 roughnesses log-spaced over 0.001–1, IOR 1.05–3 in steps
    of 0.05) and write :mod:`scene.plastic_scale_table`."""
    import textwrap

    alphas = np.round(np.geomspace(0.001, 1, 25), 5)
    etas = np.round(np.arange(1.05, 3.0001, 0.05), 3)
    rows = []
    for a in alphas:
        vals = [f"{fit_scale(float(a), float(e)):.5f}" for e in etas]
        rows.append("    (" + ",\n     ".join(", ".join(vals[k:k + 10]) for k in range(0, len(vals), 10)) + "),")

    def wrapped(name: str, values) -> str:
        return f"{name} = (\n" + "\n".join("    " + s for s in textwrap.wrap(", ".join(f"{v:g}" for v in values), 100)) + "\n)"

    from illumix.scene import plastic_scale_table

    path = path or Path(plastic_scale_table.__file__)
    head = ('"""Table of :func:`renderer_jobs.mitsuba.plastic_fit.fit_scale` (Mitsuba\'s roughplastic): written by\n'
            "``python -m illumix.renderer_jobs.mitsuba.plastic_fit``, checked against Mitsuba by ``tests/test_plastic_scale.py``.\n"
            'Rows: ``ALPHAS`` (GGX α, log-spaced); columns: ``ETAS`` (interior / exterior IOR)."""\n\n')
    path.write_text(head + wrapped("ALPHAS", alphas) + "\n" + wrapped("ETAS", etas) + "\nSCALE = (\n" + "\n".join(rows)
                    + "\n)\n")
    return path


if __name__ == "__main__":
    print(write_table())
