"""Scene translation for Cycles: a :class:`~scene.model.Scene` view as the plain-data job
the Blender worker (:mod:`renderer_jobs.cycles.worker`) renders.

Everything spectral is resolved here, on the scene grid, so the worker only copies numbers:

- **Passes** (the thesis method): pass ``p`` carries bands ``p, p + P, p + 2P`` (``P = ⌈n/3⌉``: 21
  passes for 63 bands) in its R, G, B slots; every reflectance, emission and conductor constant
  is set to its band average at those bands. Same seed in every pass.
- **Materials**: ``diffuse`` → Diffuse BSDF. ``roughplastic`` → Principled BSDF (metallic 0, GGX,
  roughness ``√α`` — Blender squares it —, IOR ``η = int/ext``) with base colour ``c ρ``: Mitsuba's
  roughplastic darkens its diffuse term by the rough-interface transmittances,
  ``ρ t(θ_i) t(θ_o) / (η² (1 − F_int))``, which the Principled BSDF does not, so ``c`` is fitted to
  Mitsuba's own term (:func:`scene.plastic_scale.plastic_diffuse_scale`: 0.73 at α = 0.25, η = 1.5; 0.93 at α = 0.08).
  Measured on the probe scene: without ``c`` Cycles is 43 % brighter; with it, within 1.3 % on the
  lit floor. (A Fresnel-weighted mix of Diffuse and Glossy was 4–16 % off: its specular weight
  ``F(n·ω_o)`` overshoots at grazing views.) ``roughconductor`` → Metallic BSDF with the
  physical-conductor Fresnel of Mitsuba's own ``η, k`` tables. ``dielectric`` → sharp Glass.
- **Emitters**: emitter-only rectangles and disks become Cycles area lights (sampled by solid angle,
  as Blender users light scenes; an emitting mesh is sampled by area and was 4× noisier on the probe's
  floor), with a black copy of the shape 10⁻⁵ of its size behind the emitting side (an emitter
  without material is black geometry that absorbs and shadows; a Cycles light lets rays through:
  +1.1 % on the demo room, whose ceiling panel hangs under a white housing, without it). Other area
  emitters stay emitting meshes; both emit from the front side only (as in Mitsuba) and are seen by
  every ray. Point and spot lights
  have radius 0 and no soft falloff; the sun has angle 0; a constant sky is the world. Spot lights
  ramp from ``beam_width`` to ``cutoff_angle`` by Blender's smoothstep in ``cos θ`` instead of
  Mitsuba's linear ramp in ``θ`` (same cone, same full-intensity core). An envmap sky is looked up
  with Mitsuba's lat-long convention and lights with its luminance × the group's spectrum
  (Mitsuba's D65): exact for a grey map; a coloured map is rendered grey, with a warning.
- **Portals** are rendered in a second setup (``"only"``) with only them emitting, as the Mitsuba
  backend does; the cube is the sum.

Shapes become triangle meshes in world space (spheres, cylinders and disks tessellated finely:
``SEGMENTS`` around), OBJ/PLY files are imported by Blender with the file's axes kept.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from illumix.renderer_jobs.cube import ALBEDO_BANDS
from illumix.renderer_jobs.mitsuba.scene_dict import group_emission  # an envmap's emission is Mitsuba's D65
from illumix.scene.plastic_scale import plastic_diffuse_scale
from illumix.scene.model import Scene
from illumix.scene.textures import is_texture
from illumix.scene.schema import (ConstantSky, Cube, Cylinder, Dielectric, DirectionalLight, Disk, EnvMapSky,
                                        MeshFile, PointLight, Rectangle, RoughConductor, RoughPlastic, SceneError,
                                        Sphere, SpotLight)

SEGMENTS = 128  # around spheres, cylinders and disks (area within 0.04 % of the true shape's)
SAMPLING_PATTERN = "TABULATED_SOBOL"
METHOD = "thesis: {n} passes x 3 fixed wavelengths (R, G, B slots), the same seed in every pass"


def band_passes(n_bands: int) -> list[list[int]]:
    """Bands carried by each pass's R, G, B slots (−1: unused): pass ``p`` → ``p, p+P, p+2P``."""
    per = math.ceil(n_bands / 3)
    return [[b if b < n_bands else -1 for b in (p, p + per, p + 2 * per)] for p in range(per)]


def conductor_constants(name: str, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Band averages of ``η, k`` of a conductor from Mitsuba's tables (``mitsuba/data/ior``)."""
    import importlib.util

    from illumix.retarget.grid import resample

    grid = scene.spectral_grid
    if name == "none":  # Mitsuba's perfect mirror
        return np.zeros(grid.n_bands), np.full(grid.n_bands, 1e4)
    spec = importlib.util.find_spec("mitsuba")
    locations = list(spec.submodule_search_locations or []) if spec else []
    if spec is not None and spec.origin and not locations:
        locations = [str(Path(spec.origin).parent)]
    root = Path(locations[0]) / "data" / "ior" if locations else None
    out = []
    for part in ("eta", "k"):
        path = root / f"{name}.{part}.spd" if root else None
        if path is None or not path.is_file():
            raise SceneError(f"conductor {name!r}: its {part} table (mitsuba/data/ior) is missing; install "
                             "the render extra (Mitsuba) for conductor tables")
        rows = [ln.split() for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
        wl, v = np.array([[float(a), float(b)] for a, b in rows]).T
        out.append(resample(wl, v, grid, extend="constant", what=f"conductor {name} {part}"))
    return out[0], out[1]


def _albedo_rgb(scene: Scene, reflectance: np.ndarray) -> list[float]:
    """Mean reflectance over the albedo AOV's broad bands (as :mod:`renderer_jobs.mitsuba.aovs`)."""
    centers = scene.spectral_grid.wavelengths
    return [float(reflectance[(centers >= a) & (centers < b)].mean()) for a, b in ALBEDO_BANDS]


def material_doc(scene: Scene, name: str, warn) -> dict:
    m = scene.materials[name]
    what = f"materials.{name}"
    if isinstance(m, Dielectric):
        return {"kind": "glass", "ior": m.int_ior / m.ext_ior, "two_sided": True, "albedo_rgb": [0, 0, 0]}
    if isinstance(m, RoughConductor):
        eta, k = conductor_constants(m.conductor, scene)
        if m.specular_reflectance is not None:
            warn(f"{what}: the cycles backend renders a conductor without specular_reflectance (Cycles' "
                 "physical-conductor Fresnel takes no tint); used the bare conductor")
        return {"kind": "conductor", "eta": eta.tolist(), "k": k.tolist(), "roughness": math.sqrt(m.alpha),
                "two_sided": m.two_sided, "albedo_rgb": [0, 0, 0]}
    if getattr(m, "normal_map", None) is not None:
        warn(f"{what}: the cycles backend renders without the normal map {m.normal_map.file!r} (flat shading "
             "normals); use --backend mitsuba to render it")
    if is_texture(m.reflectance):
        raise SceneError(f"{what}: reflectance: textures render with the Mitsuba backend only; "
                         "use --backend mitsuba (or a plain spectrum)")
    rho = scene.spectrum(m.reflectance, what)
    if isinstance(m, RoughPlastic):
        eta = m.int_ior / m.ext_ior
        return {"kind": "plastic", "diffuse": (rho * plastic_diffuse_scale(m.alpha, eta)).tolist(), "ior": eta,
                "roughness": math.sqrt(m.alpha), "two_sided": m.two_sided, "albedo_rgb": _albedo_rgb(scene, rho)}
    return {"kind": "diffuse", "reflectance": rho.tolist(), "two_sided": m.two_sided,
            "albedo_rgb": _albedo_rgb(scene, rho)}


# ---------------------------------------------------------------------------------------------
# Geometry: triangle meshes in object space, then the shape's transform


def _rectangle():
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    return v, np.array([[0, 1, 2], [0, 2, 3]]), None


def _cube():
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f), None


def _disk():
    t = 2 * np.pi * np.arange(SEGMENTS) / SEGMENTS
    v = np.concatenate([[[0, 0, 0]], np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)])
    i = np.arange(SEGMENTS)
    return v, np.stack([np.zeros_like(i), 1 + i, 1 + (i + 1) % SEGMENTS], axis=1), None


def _sphere(center, radius):
    nu, nv = SEGMENTS, SEGMENTS // 2
    th = np.pi * np.arange(1, nv) / nv
    ph = 2 * np.pi * np.arange(nu) / nu
    n = np.stack([np.outer(np.sin(th), np.cos(ph)), np.outer(np.sin(th), np.sin(ph)),
                  np.outer(np.cos(th), np.ones(nu))], axis=-1).reshape(-1, 3)
    n = np.concatenate([[[0, 0, 1]], n, [[0, 0, -1]]])
    ring = lambda r, j: 1 + r * nu + (j % nu)  # noqa: E731
    f = []
    j = np.arange(nu)
    f.append(np.stack([np.zeros(nu, int), ring(0, j), ring(0, j + 1)], axis=1))
    for r in range(nv - 2):
        a, b, c, d = ring(r, j), ring(r + 1, j), ring(r + 1, j + 1), ring(r, j + 1)
        f += [np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)]
    last = len(n) - 1
    f.append(np.stack([np.full(nu, last), ring(nv - 2, j + 1), ring(nv - 2, j)], axis=1))
    return np.asarray(center) + radius * n, np.concatenate(f), n


def _cylinder(p0, p1, radius):
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    a = np.cross(axis, [1, 0, 0] if abs(axis[0]) < 0.9 else [0, 1, 0])
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    t = 2 * np.pi * np.arange(SEGMENTS) / SEGMENTS
    n = np.outer(np.cos(t), a) + np.outer(np.sin(t), b)
    v = np.concatenate([p0 + radius * n, p1 + radius * n])
    i = np.arange(SEGMENTS)
    k = (i + 1) % SEGMENTS
    f = np.concatenate([np.stack([i, k, SEGMENTS + k], axis=1), np.stack([i, SEGMENTS + k, SEGMENTS + i], axis=1)])
    return v, f, np.concatenate([n, n])


def area_light(sh) -> dict | None:
    """An emitter-only rectangle or disk as a Blender area light (``shape``, ``size``, ``size_y``,
    world ``matrix`` with −Z along the shape's normal, ``area`` in m²), or None when its transform
    shears it (then it stays an emitting mesh)."""
    if not isinstance(sh, (Rectangle, Disk)) or sh.material is not None or sh.emitter is None:
        return None
    m = sh.transform.to_matrix() if sh.transform is not None else np.eye(4)
    ex, ey = m[:3, 0], m[:3, 1]
    sx, sy = float(np.linalg.norm(ex)), float(np.linalg.norm(ey))
    if abs(float(ex @ ey)) > 1e-6 * sx * sy:
        return None
    n = np.cross(ex, ey)
    z = -n / np.linalg.norm(n)
    x = ex / sx
    rot = np.stack([x, np.cross(z, x), z], axis=1)
    world = np.eye(4)
    world[:3, :3], world[:3, 3] = rot, m[:3, 3]
    if isinstance(sh, Rectangle):
        kind, area = "RECTANGLE", 4 * sx * sy
    else:
        kind, area = ("DISK" if abs(sx - sy) <= 1e-9 * sx else "ELLIPSE"), math.pi * sx * sy
    return {"shape": kind, "size": 2 * sx, "size_y": 2 * sy, "matrix": world.tolist(), "area": area}


def shape_mesh(sh) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(vertices (n, 3), triangles (m, 3), vertex normals (n, 3) or None)`` in world space."""
    if isinstance(sh, Rectangle):
        v, f, n = _rectangle()
    elif isinstance(sh, Cube):
        v, f, n = _cube()
    elif isinstance(sh, Disk):
        v, f, n = _disk()
    elif isinstance(sh, Sphere):
        v, f, n = _sphere(sh.center, sh.radius)
    elif isinstance(sh, Cylinder):
        v, f, n = _cylinder(sh.p0, sh.p1, sh.radius)
    else:  # pragma: no cover — meshes from files are imported by the worker
        raise SceneError(f"shapes ({sh.name}): no tessellation for {sh.type!r}")
    if sh.transform is not None:
        m = sh.transform.to_matrix()
        v = v @ m[:3, :3].T + m[:3, 3]
        if n is not None:
            n = n @ np.linalg.inv(m[:3, :3])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
    return v, f, n


# ---------------------------------------------------------------------------------------------
# The job


def _light_doc(scene: Scene, light, gid: str, emission: np.ndarray, warn=lambda msg: None) -> dict:
    radiance = (light.strength * emission).tolist()
    if isinstance(light, PointLight):
        return {"type": "point", "name": light.name, "group": gid, "position": list(light.position),
                "radiance": radiance}
    if isinstance(light, SpotLight):
        beam = light.beam_width if light.beam_width is not None else 0.75 * light.cutoff_angle
        cc, cb = math.cos(math.radians(light.cutoff_angle)), math.cos(math.radians(beam))
        return {"type": "spot", "name": light.name, "group": gid, "position": list(light.position),
                "direction": list(np.subtract(light.target, light.position)), "cutoff_deg": light.cutoff_angle,
                "blend": float((cb - cc) / (1 - cc)), "radiance": radiance}
    if isinstance(light, DirectionalLight):
        return {"type": "sun", "name": light.name, "group": gid, "direction": list(light.direction),
                "radiance": radiance}
    if isinstance(light, ConstantSky):
        return {"type": "sky", "name": light.name, "group": gid, "radiance": radiance}
    if isinstance(light, EnvMapSky):
        path = scene.resolve_path(light.filename)
        if not _grey_map(path):
            warn(f"lights ({light.name}): the cycles backend lights with the envmap's luminance × Mitsuba's "
                 "D65 (exact for a grey map); this map is coloured, so its colours are not rendered "
                 "(use --backend mitsuba for them)")
        m = light.transform.to_matrix() if light.transform is not None else np.eye(4)
        return {"type": "sky", "name": light.name, "group": gid, "radiance": radiance, "image": str(path),
                "to_local": np.linalg.inv(m[:3, :3]).tolist()}
    raise SceneError(f"lights ({light.name}): the cycles backend cannot render {light.type!r}")  # pragma: no cover


def _grey_map(path: Path) -> bool:
    """True when every pixel of the environment map has R = G = B (within 0.1 %)."""
    try:
        if path.suffix.lower() == ".exr":
            from illumix.renderer_jobs.cycles.exr import read_exr

            layers = read_exr(path)
            img = next(iter(layers.values())) if len(layers) == 1 else np.concatenate(
                [layers[k] for k in ("R", "G", "B") if k in layers], axis=-1)
        else:
            import cv2

            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
    except Exception:  # noqa: BLE001 — unreadable here: say it may be coloured
        return False
    if img is None or img.ndim < 3 or img.shape[2] < 3:
        return img is not None
    c = img[..., :3].astype(np.float64)
    return bool(np.all(np.ptp(c, axis=2) <= 1e-3 * np.maximum(c.max(axis=2), 1e-12)))


def write_job(scene: Scene, view: str, job_dir: Path, *, spp: int, seed: int,
              resolution: tuple[int, int] | None = None, illumination: bool = False,
              aov_spp: int | None = None, warn=lambda msg: None) -> dict:
    """Write ``job.json`` and ``meshes.npz`` for rendering ``view`` of ``scene`` (every group in
    one render) into ``job_dir``; returns the job document. ``aov_spp``: an AOV-only job."""
    job_dir.mkdir(parents=True, exist_ok=True)
    groups = scene.group_names
    gid = {g: f"g{i}" for i, g in enumerate(groups)}  # Blender light-group names: identifiers only
    emission = {g: np.asarray(group_emission(scene, g)[0], dtype=float) for g in groups}
    v = scene.view(view)
    used = {s.material for s in scene.shapes if s.material is not None}
    shapes, arrays = [], {}
    for i, s in enumerate(scene.shapes):
        doc: dict = {"name": s.name, "material": s.material}
        light = None if aov_spp else area_light(s)  # the AOV pass keeps meshes: they flag emitter pixels
        if light is not None:
            doc["area_light"] = light
        if isinstance(s, MeshFile):
            doc.update(file=str(scene.resolve_path(s.filename)), file_type=s.type, flat=s.face_normals,
                       matrix=(s.transform.to_matrix() if s.transform is not None else np.eye(4)).tolist())
        else:
            vert, tri, nrm = shape_mesh(s)
            if light is not None:  # the black occluder sits just behind the light's emitting side
                vert = vert + 1e-5 * max(light["size"], light["size_y"]) * np.asarray(light["matrix"])[:3, 2]  # light +Z
            key = f"s{i}"
            arrays[key + ".v"], arrays[key + ".f"] = vert.astype(np.float64), tri.astype(np.int64)
            if nrm is not None:
                arrays[key + ".n"] = nrm
            doc.update(mesh=key, smooth=nrm is not None)
        if s.emitter is not None:
            doc["emitter"] = {"group": gid[s.emitter.group], "portal": s.emitter.portal,
                              "radiance": (s.emitter.strength * emission[s.emitter.group]).tolist()}
        shapes.append(doc)
    lights = [_light_doc(scene, light, gid[light.group], emission[light.group], warn) for light in scene.lights]
    portals = any(s.emitter is not None and s.emitter.portal for s in scene.shapes)
    direct = bool(lights) or any(s.emitter is not None and not s.emitter.portal for s in scene.shapes)
    w, h = resolution or v.resolution
    job = {
        "version": 1, "scene": scene.name, "view": view, "resolution": [int(w), int(h)],
        "camera": {"origin": list(v.origin), "target": list(v.target), "up": list(v.up), "fov_deg": v.fov},
        "settings": {"spp": int(spp), "seed": int(seed), "max_bounces": max(0, scene.max_depth - 2),
                     "sampling_pattern": SAMPLING_PATTERN, "light_tree": True},
        "passes": band_passes(scene.spectral_grid.n_bands),
        "groups": [gid[g] for g in groups], "group_names": groups,
        "materials": {n: material_doc(scene, n, warn) for n in scene.materials if n in used},
        "shapes": shapes, "lights": lights,
        "setups": [] if aov_spp else [s for s, on in (("without", direct), ("only", portals)) if on],
        "modes": ["transport"] + (["illumination"] if illumination else []),
        "aov_spp": aov_spp,
    }
    (job_dir / "job.json").write_text(json.dumps(job))
    if arrays:
        np.savez(job_dir / "meshes.npz", **arrays)
    return job
