"""Scene translation: a :class:`~scene.model.Scene` as a Mitsuba 3 scene dictionary.

One (view, set of light groups) at a time: :func:`build_scene_dict` keeps every shape's geometry and
material, turns on only the chosen groups' emitters — each emitting ``strength × Ē_g`` with ``Ē_g``
the group's emission held constant over each band (:func:`step_spectrum`) and sampled in
proportion to its approximate power (:func:`emitter_power`, Mitsuba's ``sampling_weight``) — and
sets a box-filtered perspective camera. Portals (``emitter.portal``) are not geometry: ``portals=
"without"`` leaves them out, ``"only"`` keeps only them as emitters (their own pass, see
:mod:`renderer_jobs.mitsuba.render`). Also: scene bounds and radius (the power of distant lights),
and Mitsuba's D65 on the grid (what an RGB envmap emits).
"""

from __future__ import annotations

import json
import math
from functools import lru_cache

import numpy as np

from illumix.renderer_jobs.mitsuba.instance_padding import pad_registry, release_padding
from illumix.renderer_jobs.mitsuba.textures import normal_map_dict, reflectance_dict
from illumix.renderer_jobs.mitsuba.variant import RenderError, import_mitsuba
from illumix.scene.model import Scene
from illumix.scene.schema import (ConstantSky, Cube, Cylinder, Dielectric, DirectionalLight, Disk, EnvMapSky,
                                        MeshFile, PointLight, Rectangle, RoughConductor, RoughPlastic, SceneError,
                                        Sphere, SpotLight)

# How next-event estimation picks a light: "power" (by emitter_power) or "uniform" (bench/render.py
# part "samplers" measures what power weighting buys).
EMITTER_SELECTION = "power"
# Sampled wavelengths keep this fraction of a band away from its edges, where step spectra ramp
# (step_spectrum): inside, a step spectrum is exactly its band's value.
BAND_GUARD = 1 / 20
NODES_PER_BAND = 10  # nodes 2·guard apart: the band interior holds 9 spacings, the ramp one


def band_guard(step: float) -> float:
    """The guard (nm) of bands ``step`` nm wide (:data:`BAND_GUARD`)."""
    return step * BAND_GUARD


def _fmt(values) -> str:
    return ",".join(repr(float(v)) for v in values)


def step_spectrum(values: np.ndarray, scene: Scene, scale: float = 1.0) -> dict:
    """A Mitsuba spectrum holding band averages constant over each band of the scene grid.

    Uniform values become ``uniform``; otherwise a ``regular`` spectrum (evaluated by one index
    computation, not a search: issue 17 measured ``irregular`` evaluation at 3/4 of an all-bands
    path's cost) with :data:`NODES_PER_BAND` nodes per band from ``lo + guard`` to ``hi − guard``,
    all holding the band's value: the spectrum is exactly constant on ``[lo + guard, hi − guard]``,
    where every wavelength is sampled (:func:`band_guard`), and ramps across each edge. An all-zero
    spectrum becomes ``uniform`` 0 (an all-zero tabulated spectrum makes Mitsuba fail: "no
    probability mass").
    """
    v = np.asarray(values, dtype=np.float64) * scale
    if np.allclose(v, v[0], rtol=0, atol=0):
        return {"type": "uniform", "value": float(v[0])}
    if not np.any(v > 0):
        return {"type": "uniform", "value": 0.0}
    grid = scene.spectral_grid
    g = band_guard(grid.step)
    return {"type": "regular", "wavelength_min": float(grid.edges[0] + g), "wavelength_max": float(grid.edges[-1] - g),
            "values": _fmt(np.repeat(v, NODES_PER_BAND))}


def _bsdf(scene: Scene, name: str) -> dict:
    m = scene.materials[name]
    what = f"materials.{name}"
    if isinstance(m, Dielectric):
        return {"type": "dielectric", "int_ior": m.int_ior, "ext_ior": m.ext_ior}
    if isinstance(m, RoughConductor):
        d: dict = {"type": "roughconductor", "material": m.conductor, "alpha": m.alpha, "distribution": "ggx"}
        if m.specular_reflectance is not None:
            d["specular_reflectance"] = step_spectrum(scene.spectrum(m.specular_reflectance, what), scene)
    elif isinstance(m, RoughPlastic):
        d = {"type": "roughplastic", "alpha": m.alpha, "int_ior": m.int_ior, "ext_ior": m.ext_ior,
             "distribution": "ggx", "diffuse_reflectance": reflectance_dict(scene, m.reflectance, what, step_spectrum)}
    else:
        d = {"type": "diffuse", "reflectance": reflectance_dict(scene, m.reflectance, what, step_spectrum)}
    if m.normal_map is not None:
        d = {"type": "normalmap", "normalmap": normal_map_dict(scene, m.normal_map), "bsdf": d}
    return {"type": "twosided", "bsdf": d} if m.two_sided else d


def _transform(mi, matrix: np.ndarray):
    return mi.ScalarTransform4f(np.asarray(matrix, dtype=np.float64).tolist())


def _shape_dict(mi, scene: Scene, s) -> dict:
    d: dict
    if isinstance(s, Sphere):
        d = {"type": "sphere", "center": list(s.center), "radius": s.radius}
    elif isinstance(s, Cylinder):
        d = {"type": "cylinder", "p0": list(s.p0), "p1": list(s.p1), "radius": s.radius}
    elif isinstance(s, MeshFile):
        d = {"type": s.type, "filename": str(scene.resolve_path(s.filename)), "face_normals": s.face_normals}
    elif isinstance(s, (Rectangle, Cube, Disk)):
        d = {"type": s.type}
    else:  # pragma: no cover — the scene schema is closed
        raise SceneError(f"shapes ({s.name}): unsupported type {s.type!r}")
    if s.transform is not None:
        # Spheres and cylinders are placed by their own parameters; a transform applies on top.
        d["to_world"] = _transform(mi, s.transform.to_matrix())
    if s.material is not None:
        d["bsdf"] = _bsdf(scene, s.material)
    else:
        d["bsdf"] = {"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.0}}
    return d


@lru_cache(maxsize=4096)
def _shape_area(key: str) -> float:
    mi, _ = import_mitsuba()
    d = json.loads(key)
    if "to_world" in d:
        d["to_world"] = _transform(mi, np.asarray(d["to_world"]))
    d.pop("bsdf", None)
    return float(mi.load_dict(d).surface_area()[0])


def shape_area(scene: Scene, s) -> float:
    """Surface area of a shape in m² (Mitsuba's own, so meshes are included)."""
    mi, _ = import_mitsuba()
    d = _shape_dict(mi, scene, s)
    d.pop("bsdf", None)
    if "to_world" in d:
        d["to_world"] = s.transform.to_matrix().tolist()
    return _shape_area(json.dumps(d, sort_keys=True, default=float))


_CANON = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])


def shape_hull_points(scene: Scene, sh) -> np.ndarray:
    """World-space points ``(k, 3)`` (metres) whose convex hull contains the shape: its canonical
    box (or, for meshes, its bounding box) corners through its transform."""
    m = sh.transform.to_matrix() if sh.transform is not None else np.eye(4)
    if isinstance(sh, (Rectangle, Cube, Disk)):
        local = _CANON.copy()
        if not isinstance(sh, Cube):
            local[:, 2] = 0.0
        return (local @ m.T)[:, :3]
    if isinstance(sh, Sphere):
        c, r = np.asarray(sh.center), sh.radius
        return ((np.c_[c + r * _CANON[:, :3], np.ones(8)]) @ m.T)[:, :3]
    if isinstance(sh, Cylinder):
        local = np.concatenate([np.asarray(e) + sh.radius * _CANON[:, :3] for e in (sh.p0, sh.p1)])
        return (np.c_[local, np.ones(len(local))] @ m.T)[:, :3]
    mi, _ = import_mitsuba()
    d = _shape_dict(mi, scene, sh)
    d.pop("bsdf", None)
    bb = mi.load_dict(d).bbox()
    lo = np.array([float(bb.min[i]) for i in range(3)])
    hi = np.array([float(bb.max[i]) for i in range(3)])
    return lo + (hi - lo) * (_CANON[:, :3] + 1) / 2


def scene_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds ``(lo (3,), hi (3,))`` of the scene's geometry in metres (portals excluded).

    Computed from the description (Mitsuba may merge shapes, and a merged mesh reports no bounds
    before the scene is built); meshes are loaded one by one for theirs.
    """
    pts = [shape_hull_points(scene, sh) for sh in scene.shapes if not scene.is_portal(sh)]
    if not pts:
        return np.zeros(3), np.zeros(3)
    allp = np.concatenate(pts)
    return allp.min(axis=0), allp.max(axis=0)


def scene_radius(scene: Scene) -> float:
    """Radius of a sphere around the scene's geometry (for the power of distant lights); ≥ 1e-3 m."""
    lo, hi = scene_bounds(scene)
    return max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)


def emitter_power(scene: Scene, e, radius: float) -> float:
    """Approximate emitted power (per unit of the group spectrum) — the emitter sampling weight."""
    if isinstance(e, (Rectangle, Cube, Disk, Sphere, Cylinder, MeshFile)):
        return e.emitter.strength * math.pi * shape_area(scene, e)
    if isinstance(e, PointLight):
        return e.strength * 4 * math.pi
    if isinstance(e, SpotLight):
        return e.strength * 2 * math.pi * (1 - math.cos(math.radians(e.cutoff_angle)))
    if isinstance(e, DirectionalLight):
        return e.strength * math.pi * radius ** 2
    if isinstance(e, (ConstantSky, EnvMapSky)):
        return e.strength * 4 * math.pi ** 2 * radius ** 2
    raise SceneError(f"unknown emitter {e!r}")  # pragma: no cover


def _group_emission(scene: Scene, group: str) -> np.ndarray:
    if any(isinstance(e, EnvMapSky) for e in scene.emitters_of(group)):
        if scene.emission_name(group) != "flat":
            raise SceneError(f"light group {group!r}: a group with an envmap sky is rendered with "
                             "Mitsuba's D65 spectrum (the map's colour upsampling); set its emission to 'flat'")
        return mitsuba_d65(scene)
    return scene.emission(group)


def group_emission(scene: Scene, group: str) -> tuple[np.ndarray, str]:
    """``(Ē_g (n_bands,) band averages, name)`` the group's cube is rendered with."""
    e = _group_emission(scene, group)
    has_env = any(isinstance(x, EnvMapSky) for x in scene.emitters_of(group))
    return e, ("mitsuba-d65" if has_env else scene.emission_name(group))


def mitsuba_d65(scene: Scene) -> np.ndarray:
    """Band averages of Mitsuba's internal D65 (what an RGB envmap emits per unit grey), on the grid:
    over each band's sampled interior (:func:`band_guard`), midpoint rule, 20 points per band."""
    mi, dr = import_mitsuba()
    grid = scene.spectral_grid
    g = band_guard(grid.step)
    k = 20
    frac = (np.arange(k) + 0.5) / k
    fine = (grid.edges[:-1, None] + g + (grid.step - 2 * g) * frac[None, :]).ravel()
    tex = mi.load_dict({"type": "d65"})
    si = dr.zeros(mi.SurfaceInteraction3f)
    vals = []
    for chunk in np.array_split(fine, math.ceil(len(fine) / 4)):
        lam = np.pad(chunk, (0, 4 - len(chunk)), mode="edge")
        si.wavelengths = mi.Spectrum(*[float(x) for x in lam])
        out = tex.eval(si)
        vals.extend([float(out[i][0]) for i in range(len(chunk))])
    return np.asarray(vals).reshape(grid.n_bands, k).mean(axis=1)


def _emitter_dicts(mi, scene: Scene, group: str, radius: float, portals: str = "without",
                   flat_emission: bool = False) -> tuple[dict[str, dict], dict[str, dict]]:
    """``(shape emitters by shape name, other emitters by light name)`` for one group.

    ``portals``: ``"without"`` — every emitter but portals; ``"only"`` — portals only.
    ``flat_emission``: every emitter emits ``strength × 1`` in every band instead of the group's
    emission (the caller scales the bands after: linearity; not for envmaps, whose colour varies).
    """
    spectrum = np.ones(scene.spectral_grid.n_bands) if flat_emission else _group_emission(scene, group)
    shape_em: dict[str, dict] = {}
    lights: dict[str, dict] = {}
    for e in scene.emitters_of(group):
        if scene.is_portal(e) != (portals == "only"):
            continue
        w = max(emitter_power(scene, e, radius), 1e-12) if EMITTER_SELECTION == "power" else 1.0
        if hasattr(e, "emitter") and e.emitter is not None:
            shape_em[e.name] = {"type": "area", "radiance": step_spectrum(spectrum, scene, e.emitter.strength),
                                "sampling_weight": w}
        elif isinstance(e, PointLight):
            lights[e.name] = {"type": "point", "position": list(e.position),
                              "intensity": step_spectrum(spectrum, scene, e.strength), "sampling_weight": w}
        elif isinstance(e, SpotLight):
            d = np.subtract(e.target, e.position)
            up = (0, 1, 0) if abs(d[1]) < 0.99 * np.linalg.norm(d) else (1, 0, 0)
            lights[e.name] = {"type": "spot", "to_world": mi.ScalarTransform4f().look_at(
                origin=list(e.position), target=list(e.target), up=list(up)),
                "intensity": step_spectrum(spectrum, scene, e.strength), "cutoff_angle": e.cutoff_angle,
                "beam_width": e.beam_width if e.beam_width is not None else 0.75 * e.cutoff_angle,
                "sampling_weight": w}
        elif isinstance(e, DirectionalLight):
            lights[e.name] = {"type": "directional", "direction": list(e.direction),
                              "irradiance": step_spectrum(spectrum, scene, e.strength), "sampling_weight": w}
        elif isinstance(e, ConstantSky):
            lights[e.name] = {"type": "constant", "radiance": step_spectrum(spectrum, scene, e.strength),
                              "sampling_weight": w}
        elif isinstance(e, EnvMapSky):
            d = {"type": "envmap", "filename": str(scene.resolve_path(e.filename)), "scale": e.strength,
                 "sampling_weight": w}
            if e.transform is not None:
                d["to_world"] = _transform(mi, e.transform.to_matrix())
            lights[e.name] = d
    return shape_em, lights


def sensor_dict(mi, scene: Scene, view: str, resolution: tuple[int, int] | None = None) -> dict:
    v = scene.view(view)
    w, h = resolution or v.resolution
    return {"type": "perspective", "fov": v.fov, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(v.origin), target=list(v.target), up=list(v.up)),
            "film": {"type": "hdrfilm", "width": int(w), "height": int(h), "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": 1}}


def batch_sensor_dict(mi, scene: Scene, views: list[str], resolution: tuple[int, int], spp: int = 1) -> dict:
    """One Mitsuba ``batch`` sensor rendering ``views`` side by side into a ``(H, len(views) · W)``
    film: one render call (one kernel) for many small views — what the view probe and previews use.
    Split the result with ``np.split(image, len(views), axis=1)``."""
    w, h = resolution
    return {"type": "batch", **{f"view{i}": sensor_dict(mi, scene, v, resolution) for i, v in enumerate(views)},
            "film": {"type": "hdrfilm", "width": int(w) * len(views), "height": int(h), "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": int(spp)}}


def build_scene_dict(scene: Scene, view: str, groups: list[str] | None, *,
                     resolution: tuple[int, int] | None = None, radius: float | None = None,
                     portals: str = "without", flat_emission: bool = False) -> dict:
    """Mitsuba ``load_dict`` document of ``scene`` seen from ``view`` with only ``groups`` lit
    (``None`` = every group on; ``[]`` = all dark, geometry only). ``portals="without"`` leaves
    portal shapes out entirely; ``"only"`` keeps only the groups' portals as emitters (the geometry
    stays, the other emitters go). ``flat_emission``: see :func:`_emitter_dicts`."""
    mi, _ = import_mitsuba()
    groups = scene.group_names if groups is None else groups
    if radius is None:
        radius = scene_radius(scene) if groups else 1.0
    doc: dict = {"type": "scene",
                 "integrator": {"type": "path", "max_depth": scene.max_depth, "hide_emitters": False},
                 "sensor": sensor_dict(mi, scene, view, resolution)}
    shape_em: dict[str, dict] = {}
    for g in groups:
        se, lights = _emitter_dicts(mi, scene, g, radius, portals, flat_emission)
        shape_em.update(se)
        for name, d in lights.items():
            doc[f"light_{name}"] = d
    bsdf_ids: dict[str, str] = {}
    for s in scene.shapes:
        if scene.is_portal(s) and s.name not in shape_em:
            continue  # a portal is not geometry: present only as its own pass's emitter
        d = _shape_dict(mi, scene, s)
        # One BSDF per material, shared by its shapes (not one per shape): fewer instances for every
        # call to record, and a BSDF count that follows the materials, not the shapes
        # (:mod:`.instance_padding`: scenes that differ in shapes share kernels).
        key = s.material or ""
        if key not in bsdf_ids:
            bsdf_ids[key] = f"bsdf{len(bsdf_ids)}"
            doc[bsdf_ids[key]] = d["bsdf"]
        d["bsdf"] = {"type": "ref", "id": bsdf_ids[key]}
        if s.name in shape_em:
            d["emitter"] = shape_em[s.name]
        doc[f"shape_{s.name}"] = d
    return doc


def load_padded(mi, doc: dict):
    """``mi.load_dict(doc)`` with the instance registry padded (:mod:`.instance_padding`): kernels
    recorded for this scene are the ones a scene of similar size already compiled.

    Without Mitsuba's ``optimize`` step: it merges shapes in an order that changes from load to load,
    and light sampling picks emitters by their order in the scene, so the same seed gave a different,
    equally valid cube on every load (generated room 9106: three renders, two different image sums;
    without it: the same shape order on every load, bit-identical cubes, the same CPU per render
    within noise: 7.5 s against 7.6–8.4 s at 160×120, 64 spp)."""
    release_padding()
    ms = mi.load_dict(doc, optimize=False)
    pad_registry(mi)
    return ms


def load_mitsuba_scene(scene: Scene, view: str, groups: list[str] | None, resolution=None, radius=None,
                       portals="without", flat_emission: bool = False, sampler: dict | None = None):
    """``(mitsuba Scene, its sensor)`` of :func:`build_scene_dict`; a Mitsuba failure is a :class:`RenderError`.
    ``sampler``: the sensor's sampler dictionary (default: independent, 1 sample)."""
    mi, _ = import_mitsuba()
    doc = build_scene_dict(scene, view, groups, resolution=resolution, radius=radius, portals=portals,
                           flat_emission=flat_emission)
    if sampler is not None:
        doc["sensor"]["sampler"] = sampler
    try:
        ms = load_padded(mi, doc)
    except SceneError:
        raise
    except Exception as exc:
        raise RenderError(f"scene {scene.name!r}: Mitsuba could not load it: {str(exc).splitlines()[0]}") from None
    return ms, ms.sensors()[0]
