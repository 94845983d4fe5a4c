"""The spectral export (``--format exr``): every view's stored cubes as spectral OpenEXR.

Per view (a place ``<scene>-<view>``), per light group: ``<place>/<place>_<group>.exr``, the transport
cube (the view's radiance under the group's recorded emission, ``illumixEmission``), and, where the
store has it, ``<place>/<place>_<group>_illumination.exr`` (the radiance a white Lambertian surface
at the first hit would send, same emission: illumix's physical ground truth). Relighting to any
illuminant Φ is the per-band scale ``Φ̄/Ē`` (DESIGN.md). ``split.json`` splits places by scene as
the other formats do; ``cubes.json`` lists each file's scene, view, group, kind and emission.
``--size`` resamples by area (the service's ``resize_image``).
"""

from __future__ import annotations

from illumix.dataset_export.card import LICENCES
from illumix.imagefiles.spectral_exr import spectrum_attribute, write_spectral_exr


def export_cubes(st, places, journal, o, summary: dict, on_progress) -> None:
    """Write the spectral EXRs (module docstring); fills ``summary``."""
    from illumix.engine.extra_outputs import resize_image

    # one place per view: the plan never repeats a view under the same (empty) lighting
    jobs = [(p, g, kind) for p in places for g in p.groups for kind in ("transport", "illumination")
            if kind == "transport" or _has_illumination(st.cube_meta(p.scene, p.view, g))]
    if on_progress:
        on_progress(len(jobs), None)
    index, clipped = {}, 0
    for p, g, kind in jobs:
        meta = st.cube_meta(p.scene, p.view, g)
        wl = meta.spectral_grid.wavelengths
        safe_group = g.replace("_", "-")
        rel = f"{p.name}/{p.name}_{safe_group}{'_illumination' if kind == 'illumination' else ''}.exr"
        attrs = {"illumixScene": p.scene, "illumixView": p.view, "illumixGroup": g, "illumixKind": kind,
                 "illumixEmissionName": meta.emission_name,
                 "illumixEmission": spectrum_attribute(wl, meta.emission or [1.0] * len(wl)),
                 "illumixUnits": "relative radiance per unit emission, band integrals over the grid's bands"}
        if not journal.complete(rel):
            def write(path, p=p, g=g, kind=kind, attrs=attrs, wl=wl):
                nonlocal clipped
                cube = st.read_cube(p.scene, p.view, g, kind=kind)
                if o.size:
                    cube = resize_image(cube, *o.size)
                clipped += write_spectral_exr(path, cube, wl, dtype=o.exr_dtype, attributes=attrs)
            journal.write(rel, write)
        index[rel] = {k.removeprefix("illumix").lower(): v for k, v in attrs.items() if k != "illumixEmission"} | {
            "emission": list(map(float, meta.emission or [1.0] * len(wl)))}
        if on_progress:
            on_progress(1, rel)
    journal.write_json("cubes.json", index)
    journal.write_json("split.json", summary["splits"])  # the exported places only (run.export_dataset)
    summary |= {"counts": {"views": len(places), "spectral EXR files": len(jobs),
                                             "bands": len(wl), "values clipped to float16": clipped},
                "layout": (f"`<place>/<place>_<group>.exr` (transport) and `<place>_<group>_illumination.exr`, one "
                           f"`S0.<λ>nm` channel per band ({o.exr_dtype}, Fichet et al. 2021), `cubes.json`, `split.json`. "
                           f"Units: relative radiance per unit of the group's recorded emission, each channel the "
                           f"integral over its {meta.spectral_grid.step:g} nm band (`illumixBandWidthNm`; `emissiveUnits` says "
                           "relative): divide by the band width for a spectral density per nm."),
                "reading": ("`from imagefiles.spectral_exr import read_spectral_exr; wavelengths, cube, header = read_spectral_exr(path)`"
                            " or any reader of Fichet et al.'s layout (colour-science's `read_spectral_image_Fichet2021`)."),
                "licences": [LICENCES["scenes"]],
                "cameras": [], "illuminants": {}}


def _has_illumination(meta) -> bool:
    return meta.illumination is not None and meta.illumination.storage is not None
