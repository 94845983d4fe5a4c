"""The Mitsuba 3 backend: one spectral transport cube per (view, light group), plus view AOVs.

Mitsuba stays behind this module: callers pass a :class:`renderer_jobs.scene.Scene` and get numpy.

Variant selection (:func:`select_variant`, before ``mitsuba`` is first imported):
``cuda_ad_spectral`` when a CUDA GPU is usable; else ``llvm_ad_spectral`` after locating a libLLVM
≥ 16 (``/usr/lib/llvm-*/lib``, ``/usr/lib/x86_64-linux-gnu``; LLVM ≤ 15 crashes Mitsuba 3.9) and
setting ``DRJIT_LIBLLVM_PATH``; else ``scalar_spectral`` with a warning (slow). ``ILLUMIX_MITSUBA_VARIANT``
forces a variant.

What a cube is
--------------
``T[v, g](x, λ_i)`` — for view ``v`` and light group ``g`` — is the band average over band ``i`` of the
spectral radiance reaching pixel ``x`` (box pixel filter) when only ``g``'s emitters are on, each
emitting ``strength × Ē_g(λ)`` with ``Ē_g`` the group's emission (flat, value 1, by default) held
constant over each band; every other group's emitters are removed (their geometry and materials
stay). Path tracing (Mitsuba's ``path`` integrator, unidirectional with next-event estimation,
emitter selection weighted by approximate power via ``sampling_weight``), no denoiser, no clamping,
emitters visible. Portal emitters (``emitter.portal``, e.g. the sky filling a window) are not
geometry: they are traced in a second pass with the same schedule and added (linearity), so they
never shadow the group's other emitters. Non-finite samples (none seen so far) are dropped and
counted in the cube's stats.

Wavelength sampling (issue 4, see ``bench/render.py`` for the measurements)
-------------------------------------------------------------------------
Mitsuba traces 4 wavelengths per path ("hero" wavelengths). Its spectral film draws them at random
over the whole range, so each 5 nm band of a pixel receives a *random number* of samples and the
per-band estimate carries that count's binomial noise (≈ 1/√(expected count): 12 % at 1024 spp for
63 bands). This backend drives the integrator itself (``Integrator.sample`` on rays it generates) and
chooses every wavelength:

- ``"stratified"`` (default): path ``s`` of pixel ``p`` starts at band ``k = (s + o_p) mod n`` and its
  four wavelengths lie in bands ``k, k+16, k+32, k+48 (mod n)`` — spread over the spectrum so one
  path's noise does not pile up in one camera channel — each uniformly jittered inside its band.
  Every ``n`` consecutive paths put exactly 4 samples in every band, so a band's sample count is
  fixed (⌊4·spp/n⌋ or one more, known exactly) and its estimate is the plain mean of its samples.
  ``o_p`` is a per-pixel hash that decorrelates neighbouring pixels when spp < n.
- ``"random"``: Mitsuba's default behaviour, for comparison — four wavelengths uniform over the grid
  span with Mitsuba's shifted stratification (``sample_shifted``), each band estimated as
  ``Σ L / E[count]`` exactly as the ``specfilm`` does.

Per-band sums are accumulated in float64 by ``numpy.bincount`` (no atomics), so the same seed gives
the same cube bit for bit.
"""

from __future__ import annotations

import glob
import logging
import math
import os
import re
import time
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from renderer_jobs.scene import (ConstantSky, Cube, Cylinder, Dielectric, DirectionalLight, Disk, EnvMapSky,
                                 MeshFile, PointLight, Rectangle, RoughConductor, RoughPlastic, Scene,
                                 SceneError, Sphere, SpotLight)

log = logging.getLogger(__name__)

VARIANTS = ("cuda_ad_spectral", "llvm_ad_spectral", "scalar_spectral")
MIN_LLVM = 16
LLVM_DIRS = ("/usr/lib/llvm-*/lib", "/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/local/lib",
             "/usr/lib/aarch64-linux-gnu")
WAVELENGTH_MODES = ("stratified", "random")
_EDGE_GUARD_NM = 1e-3  # keep sampled wavelengths this far inside band edges (step spectra ramps)
_LANE_STRIDE = 16      # band offset between a path's 4 wavelengths in "stratified" mode


class RenderError(RuntimeError):
    """The renderer could not run (no usable Mitsuba variant, a Mitsuba failure)."""


# ---------------------------------------------------------------------------------------------
# Variant selection


def _llvm_version(path: str) -> tuple[int, ...] | None:
    name = os.path.basename(path)
    m = re.match(r"libLLVM-(\d+)(?:\.(\d+))?(?:\.(\d+))?", name) or re.match(r"libLLVM\.so\.(\d+)(?:\.(\d+))?", name)
    if m:
        return tuple(int(g) for g in m.groups() if g is not None)
    m = re.search(r"/llvm-(\d+)/", path)
    if m and name.startswith("libLLVM") and ".so" in name:
        return (int(m.group(1)),)
    return None


def find_libllvm(min_version: int = MIN_LLVM, dirs: tuple[str, ...] = LLVM_DIRS) -> tuple[str, tuple[int, ...]] | None:
    """The newest shared libLLVM with major version ≥ ``min_version``: ``(path, version)`` or None.

    Looks at ``libLLVM*.so*`` in ``dirs`` (globs allowed). Static archives and LLVM ≤ 15 are refused.
    """
    found: list[tuple[tuple[int, ...], str]] = []
    for d in dirs:
        for p in glob.glob(os.path.join(d, "libLLVM*.so*")):
            v = _llvm_version(p)
            if v is None or v[0] < min_version or not os.path.isfile(p):
                continue
            found.append((v, p))
    if not found:
        return None
    found.sort(key=lambda t: (t[0], -len(t[1])), reverse=True)
    v, p = found[0]
    return p, v


def _cuda_available() -> bool:
    if os.environ.get("CUDA_VISIBLE_DEVICES", None) in ("", "-1"):
        return False
    if not (glob.glob("/dev/nvidia[0-9]*") or glob.glob("/usr/lib/x86_64-linux-gnu/libcuda.so*")):
        return False
    return True


_STATE: dict[str, Any] = {}


def select_variant(prefer: str | None = None) -> str:
    """Choose and activate a spectral Mitsuba variant (see module docstring); returns its name.

    ``prefer`` (or ``ILLUMIX_MITSUBA_VARIANT``) forces one of :data:`VARIANTS`. Idempotent.
    """
    if "variant" in _STATE and prefer in (None, _STATE["variant"]):
        return _STATE["variant"]
    forced = prefer or os.environ.get("ILLUMIX_MITSUBA_VARIANT") or None
    if forced is not None and forced not in VARIANTS:
        raise RenderError(f"unknown Mitsuba variant {forced!r}; choose one of {', '.join(VARIANTS)}")
    candidates = [forced] if forced else list(VARIANTS)
    if "llvm_ad_spectral" in candidates:
        env = os.environ.get("DRJIT_LIBLLVM_PATH")
        env_v = _llvm_version(env) if env else None
        if env and os.path.isfile(env) and (env_v is None or env_v[0] >= MIN_LLVM):
            _STATE["libllvm"] = env
        else:
            hit = find_libllvm()
            if hit is None:
                if forced:
                    raise RenderError(f"variant llvm_ad_spectral needs libLLVM >= {MIN_LLVM} (found none in "
                                      f"{', '.join(LLVM_DIRS)}); on Debian: apt-get install libllvm19")
                candidates.remove("llvm_ad_spectral")
            else:
                if env:
                    warnings.warn(f"DRJIT_LIBLLVM_PATH={env} is LLVM {env_v[0] if env_v else '?'} (< {MIN_LLVM}, "
                                  f"crashes Mitsuba); using {hit[0]}", stacklevel=2)
                os.environ["DRJIT_LIBLLVM_PATH"] = hit[0]
                _STATE["libllvm"] = hit[0]
    if "cuda_ad_spectral" in candidates and not forced and not _cuda_available():
        candidates.remove("cuda_ad_spectral")
    import mitsuba as mi

    errors = []
    for v in candidates:
        try:
            mi.set_variant(v)
            if v != "scalar_spectral":
                # Touch the backend: a missing GPU / bad LLVM fails here rather than mid-render.
                import drjit as dr

                dr.eval(mi.Float(1.0) + 1.0)
        except Exception as exc:  # noqa: BLE001 — any failure means "try the next variant"
            errors.append(f"{v}: {exc}")
            continue
        if v == "scalar_spectral":
            warnings.warn("Mitsuba: no GPU and no libLLVM >= 16 found; using scalar_spectral (slow). "
                          "Install libllvm19 for the vectorised CPU variant.", stacklevel=2)
        _STATE["variant"] = v
        return v
    raise RenderError("no usable Mitsuba spectral variant: " + "; ".join(errors))


def _mi():
    select_variant()
    import drjit as dr
    import mitsuba as mi

    return mi, dr


def mitsuba_version() -> str:
    import mitsuba as mi

    return str(mi.__version__)


# ---------------------------------------------------------------------------------------------
# Scene translation


def _fmt(values) -> str:
    return ",".join(repr(float(v)) for v in values)


def step_spectrum(values: np.ndarray, scene: Scene, scale: float = 1.0) -> dict:
    """A Mitsuba spectrum holding band averages constant over each band of the scene grid.

    Uniform values become ``uniform``; otherwise an ``irregular`` spectrum with nodes just inside
    the band edges. An all-zero spectrum becomes ``uniform`` 0 (an all-zero ``irregular`` spectrum
    makes Mitsuba fail: "no probability mass").
    """
    v = np.asarray(values, dtype=np.float64) * scale
    if np.allclose(v, v[0], rtol=0, atol=0):
        return {"type": "uniform", "value": float(v[0])}
    if not np.any(v > 0):
        return {"type": "uniform", "value": 0.0}
    edges = scene.spectral_grid.edges
    wl = np.empty(2 * len(v))
    wl[0::2] = edges[:-1] + _EDGE_GUARD_NM / 2
    wl[1::2] = edges[1:] - _EDGE_GUARD_NM / 2
    return {"type": "irregular", "wavelengths": _fmt(wl), "values": _fmt(np.repeat(v, 2))}


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
             "distribution": "ggx", "diffuse_reflectance": step_spectrum(scene.spectrum(m.reflectance, what), scene)}
    else:
        d = {"type": "diffuse", "reflectance": step_spectrum(scene.spectrum(m.reflectance, what), scene)}
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
    mi, _ = _mi()
    import json

    d = json.loads(key)
    if "to_world" in d:
        d["to_world"] = _transform(mi, np.asarray(d["to_world"]))
    d.pop("bsdf", None)
    return float(mi.load_dict(d).surface_area()[0])


def shape_area(scene: Scene, s) -> float:
    """Surface area of a shape in m² (Mitsuba's own, so meshes are included)."""
    import json

    mi, _ = _mi()
    d = _shape_dict(mi, scene, s)
    d.pop("bsdf", None)
    if "to_world" in d:
        d["to_world"] = s.transform.to_matrix().tolist()
    return _shape_area(json.dumps(d, sort_keys=True, default=float))


def scene_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds ``(lo (3,), hi (3,))`` of the scene's geometry in metres (portals excluded).

    Computed from the description (Mitsuba may merge shapes, and a merged mesh reports no bounds
    before the scene is built); meshes are loaded one by one for theirs.
    """
    pts: list[np.ndarray] = []
    canon = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    for sh in scene.shapes:
        if scene.is_portal(sh):
            continue
        m = sh.transform.to_matrix() if sh.transform is not None else np.eye(4)
        if isinstance(sh, (Rectangle, Cube, Disk)):
            local = canon.copy()
            if not isinstance(sh, Cube):
                local[:, 2] = 0.0
            pts.append((local @ m.T)[:, :3])
        elif isinstance(sh, Sphere):
            c, r = np.asarray(sh.center), sh.radius
            pts.append(((np.c_[c + r * canon[:, :3], np.ones(8)]) @ m.T)[:, :3])
        elif isinstance(sh, Cylinder):
            ends = np.array([sh.p0, sh.p1])
            local = np.concatenate([e + sh.radius * canon[:, :3] for e in ends])
            pts.append((np.c_[local, np.ones(len(local))] @ m.T)[:, :3])
        else:
            mi, _ = _mi()
            d = _shape_dict(mi, scene, sh)
            d.pop("bsdf", None)
            bb = mi.load_dict(d).bbox()
            pts.append(np.array([[float(bb.min[i]) for i in range(3)], [float(bb.max[i]) for i in range(3)]]))
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
    """Band averages of Mitsuba's internal D65 (what an RGB envmap emits per unit grey), on the grid."""
    mi, dr = _mi()
    grid = scene.spectral_grid
    fine = np.linspace(grid.edges[0], grid.edges[-1], 20 * grid.n_bands + 1)
    tex = mi.load_dict({"type": "d65"})
    si = dr.zeros(mi.SurfaceInteraction3f)
    vals = []
    for chunk in np.array_split(fine, math.ceil(len(fine) / 4)):
        lam = np.pad(chunk, (0, 4 - len(chunk)), mode="edge")
        si.wavelengths = mi.Spectrum(*[float(x) for x in lam])
        out = tex.eval(si)
        vals.extend([float(out[i][0]) for i in range(len(chunk))])
    from retarget.grid import resample

    return resample(fine, np.asarray(vals), grid)


PORTAL_PASSES = ("without", "only")


def _emitter_dicts(mi, scene: Scene, group: str, radius: float, portals: str = "without"
                   ) -> tuple[dict[str, dict], dict[str, dict]]:
    """``(shape emitters by shape name, other emitters by light name)`` for one group.

    ``portals``: ``"without"`` — every emitter but portals; ``"only"`` — portals only.
    """
    spectrum = _group_emission(scene, group)
    shape_em: dict[str, dict] = {}
    lights: dict[str, dict] = {}
    for e in scene.emitters_of(group):
        if scene.is_portal(e) != (portals == "only"):
            continue
        w = max(emitter_power(scene, e, radius), 1e-12)
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


def _sensor_dict(mi, scene: Scene, view: str, resolution: tuple[int, int] | None = None) -> dict:
    v = scene.view(view)
    w, h = resolution or v.resolution
    return {"type": "perspective", "fov": v.fov, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(v.origin), target=list(v.target), up=list(v.up)),
            "film": {"type": "hdrfilm", "width": int(w), "height": int(h), "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": 1}}


def build_scene_dict(scene: Scene, view: str, groups: list[str] | None, *,
                     resolution: tuple[int, int] | None = None, radius: float | None = None,
                     portals: str = "without") -> dict:
    """Mitsuba ``load_dict`` document of ``scene`` seen from ``view`` with only ``groups`` lit
    (``None`` = every group on; ``[]`` = all dark, geometry only). ``portals="without"`` leaves
    portal shapes out entirely; ``"only"`` keeps only the groups' portals as emitters (the geometry
    stays, the other emitters go)."""
    mi, _ = _mi()
    groups = scene.group_names if groups is None else groups
    if radius is None:
        radius = scene_radius(scene) if groups else 1.0
    doc: dict = {"type": "scene",
                 "integrator": {"type": "path", "max_depth": scene.max_depth, "hide_emitters": False},
                 "sensor": _sensor_dict(mi, scene, view, resolution)}
    shape_em: dict[str, dict] = {}
    for g in groups:
        se, lights = _emitter_dicts(mi, scene, g, radius, portals)
        shape_em.update(se)
        for name, d in lights.items():
            doc[f"light_{name}"] = d
    for s in scene.shapes:
        if scene.is_portal(s) and s.name not in shape_em:
            continue  # a portal is not geometry: present only as its own pass's emitter
        d = _shape_dict(mi, scene, s)
        if s.name in shape_em:
            d["emitter"] = shape_em[s.name]
        doc[f"shape_{s.name}"] = d
    return doc


def _load(scene: Scene, view: str, groups: list[str] | None, resolution=None, radius=None, portals="without"):
    mi, _ = _mi()
    try:
        ms = mi.load_dict(build_scene_dict(scene, view, groups, resolution=resolution, radius=radius,
                                           portals=portals))
    except SceneError:
        raise
    except Exception as exc:
        raise RenderError(f"scene {scene.name!r}: Mitsuba could not load it: {str(exc).splitlines()[0]}") from None
    return ms, ms.sensors()[0]


# ---------------------------------------------------------------------------------------------
# Rendering


@dataclass(frozen=True)
class RenderSettings:
    """spp: paths per pixel (each carries 4 wavelengths); seed: RNG seed of the cube;
    wavelengths: ``"stratified"`` or ``"random"`` (module docstring); max_lanes: paths traced per pass
    (bounds memory: ~1 kB per lane on the LLVM backend); aov_spp: samples per pixel of the AOV pass."""

    spp: int = 64
    seed: int = 0
    wavelengths: str = "stratified"
    max_lanes: int = 1 << 20
    aov_spp: int = 4
    resolution: tuple[int, int] | None = None  # (width, height) overriding the view's

    def __post_init__(self) -> None:
        if self.spp < 1:
            raise SceneError(f"spp must be >= 1, got {self.spp}")
        if self.wavelengths not in WAVELENGTH_MODES:
            raise SceneError(f"wavelength sampling {self.wavelengths!r} unknown; use one of {', '.join(WAVELENGTH_MODES)}")
        if self.max_lanes < 1:
            raise SceneError("max_lanes must be >= 1")

    def to_dict(self) -> dict:
        return {"spp": self.spp, "seed": self.seed, "wavelengths": self.wavelengths,
                "max_lanes": self.max_lanes, "aov_spp": self.aov_spp,
                "resolution": list(self.resolution) if self.resolution else None}


@dataclass
class CubeResult:
    """A rendered cube ``(H, W, n_bands)`` float32 of band averages, with what it was rendered with."""

    cube: np.ndarray
    emission: np.ndarray
    emission_name: str
    renderer: dict
    stats: dict = field(default_factory=dict)


def _hash_u32(x: np.ndarray, salt: int) -> np.ndarray:
    """A 32-bit integer hash (lowbias32) of ``x`` with ``salt``; vectorised, uint64 → uint64 < 2³²."""
    x = (x.astype(np.uint64) ^ np.uint64(salt & 0xFFFFFFFF)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    return x


def band_counts(n_pixels: int, n_bands: int, spp: int, seed: int) -> np.ndarray:
    """Exact samples per (pixel, band) of the ``"stratified"`` schedule: ``(n_pixels, n_bands)`` int."""
    off = (_hash_u32(np.arange(n_pixels), seed ^ 0x5BD1E995) % np.uint64(n_bands)).astype(np.int64)
    q, r = divmod(spp, n_bands)
    b = np.arange(n_bands)
    counts = np.zeros((n_pixels, n_bands), dtype=np.int64)
    for i in range(4):
        counts += q + (((b[None, :] - off[:, None] - _LANE_STRIDE * i) % n_bands) < r)
    return counts


def _pass_sizes(spp: int, n_pixels: int, max_lanes: int) -> list[int]:
    per = max(1, min(spp, max_lanes // max(n_pixels, 1)))
    sizes = [per] * (spp // per)
    if spp % per:
        sizes.append(spp % per)
    return sizes


def _aligned(a: np.ndarray) -> np.ndarray:
    """A 64-byte aligned contiguous float32 copy: Dr.Jit emits different (uncached) kernels for
    differently aligned input buffers, so every input gets the same alignment."""
    a = np.asarray(a, dtype=np.float32).ravel()
    buf = np.empty(a.size + 16, dtype=np.float32)
    k = (-buf.ctypes.data % 64) // 4
    out = buf[k:k + a.size]
    out[...] = a
    return out


class _Tracer:
    """Mitsuba scene + sensor + integrator for one (view, set of groups), reused across passes."""

    def __init__(self, scene: Scene, view: str, groups: list[str] | None, resolution=None, portals="without"):
        self.mi, self.dr = _mi()
        self.scene = scene
        self.ms, self.sensor = _load(scene, view, groups, resolution, portals=portals)
        self.integrator = self.ms.integrator()
        size = self.sensor.film().crop_size()
        self.width, self.height = int(size[0]), int(size[1])
        self.grid = scene.spectral_grid

    def trace(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, seed: int) -> np.ndarray:
        """Radiance ``(n, 4)`` float32 of paths through pixels ``pix`` (flat index, row-major from the
        top-left) at sub-pixel offsets ``jitter (n, 2)`` carrying ``wavelengths (n, 4)`` nm."""
        mi, dr = self.mi, self.dr
        n = len(pix)
        sampler = self.sensor.sampler().clone()
        sampler.seed(dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), n)
        px = (pix % self.width).astype(np.float32) + jitter[:, 0]
        py = (pix // self.width).astype(np.float32) + jitter[:, 1]
        pos = mi.Point2f(mi.Float(_aligned(px / self.width)), mi.Float(_aligned(py / self.height)))
        ray, _ = self.sensor.sample_ray_differential(0.0, mi.Float(0.5), pos, mi.Point2f(0.5, 0.5))
        ray.wavelengths = type(ray.wavelengths)(*[mi.Float(_aligned(wavelengths[:, i]))
                                                  for i in range(4)])
        spec, valid, _ = self.integrator.sample(self.ms, sampler, ray, None, True)
        spec = mi.unpolarized_spectrum(spec)
        dr.eval(spec)
        out = np.stack([np.asarray(spec[i], dtype=np.float32) for i in range(4)], axis=1)
        return out

    def first_hit(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray) -> dict[str, np.ndarray]:
        """Primary-hit AOVs per sample: albedo ``(n, 4)``, normal ``(n, 3)``, distance ``(n,)``, hit ``(n,)``."""
        mi, dr = self.mi, self.dr
        px = (pix % self.width).astype(np.float32) + jitter[:, 0]
        py = (pix // self.width).astype(np.float32) + jitter[:, 1]
        pos = mi.Point2f(mi.Float(_aligned(px / self.width)), mi.Float(_aligned(py / self.height)))
        ray, _ = self.sensor.sample_ray(0.0, mi.Float(0.5), pos, mi.Point2f(0.5, 0.5))
        ray.wavelengths = type(ray.wavelengths)(*[mi.Float(_aligned(wavelengths[:, i]))
                                                  for i in range(4)])
        si = self.ms.ray_intersect(ray)
        valid = si.is_valid()
        bsdf = si.bsdf(ray)
        alb = bsdf.eval_diffuse_reflectance(si, valid)
        n = si.sh_frame.n
        return {"albedo": np.stack([np.asarray(alb[i]) for i in range(4)], axis=1),
                "normal": np.stack([np.asarray(n[i]) for i in range(3)], axis=1),
                "distance": np.asarray(dr.select(valid, si.t, 0.0)),
                "hit": np.asarray(valid, dtype=bool)}


def render_cube(scene: Scene, view: str, group: str | list[str] | None,
                settings: RenderSettings = RenderSettings()) -> CubeResult:
    """Render the transport cube of ``view`` lit by ``group`` (see module docstring).

    ``group`` may be a list of groups (rendered together, all with their own emission) or ``None``
    for every group at once (the "all-on" render used to check additivity). Returns float32 band
    averages ``(H, W, n_bands)`` of radiance per unit emission spectrum.
    """
    groups = [group] if isinstance(group, str) else (scene.group_names if group is None else list(group))
    for g in groups:
        scene.group(g)
    t0 = time.perf_counter()
    # Portals render in a pass of their own (they occlude nothing); the cube is the passes' sum.
    passes = [p for p, present in (
        ("without", any(not scene.is_portal(e) for g in groups for e in scene.emitters_of(g))),
        ("only", any(scene.is_portal(e) for g in groups for e in scene.emitters_of(g)))) if present]
    tracers = [_Tracer(scene, view, groups, settings.resolution, portals=p) for p in passes]
    t_load = time.perf_counter() - t0
    grid = tracers[0].grid
    nb = grid.n_bands
    w, h = tracers[0].width, tracers[0].height
    npix = w * h
    if settings.wavelengths == "stratified" and 4 * settings.spp < nb:
        raise SceneError(f"spp {settings.spp} is too low for stratified wavelengths: every band of the "
                         f"{nb}-band grid needs a sample, so spp >= {math.ceil(nb / 4)}")
    acc = np.zeros(npix * nb, dtype=np.float64)
    lo = grid.edges[0]
    step = grid.step
    guard = min(_EDGE_GUARD_NM, step / 10)
    off = (_hash_u32(np.arange(npix), settings.seed ^ 0x5BD1E995) % np.uint64(nb)).astype(np.int64)
    s0 = 0
    n_bad = 0
    t_trace = 0.0
    for k, spp_pass in enumerate(_pass_sizes(settings.spp, npix, settings.max_lanes)):
        rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, k, 0x1C0])
        pix = np.repeat(np.arange(npix, dtype=np.int64), spp_pass)
        s = s0 + np.tile(np.arange(spp_pass, dtype=np.int64), npix)
        jitter = rng.random((len(pix), 2), dtype=np.float32)
        u = rng.random((len(pix), 4))
        if settings.wavelengths == "stratified":
            base = (s + off[pix]) % nb
            bands = (base[:, None] + _LANE_STRIDE * np.arange(4)[None, :]) % nb
            lam = lo + step * bands + guard + (step - 2 * guard) * u
        else:
            # Mitsuba's default: one uniform sample over the span, shifted by 1/4 for the others.
            span = nb * step
            u0 = u[:, :1]
            frac = (u0 + np.arange(4)[None, :] / 4.0) % 1.0
            lam = lo + span * frac
            bands = np.minimum((frac * nb).astype(np.int64), nb - 1)
        idx = (pix[:, None] * nb + bands).ravel()
        for j, tracer in enumerate(tracers):
            t1 = time.perf_counter()
            L = tracer.trace(pix, jitter, lam.astype(np.float32),
                             seed=int(_hash_u32(np.array([k * 8 + j]), settings.seed)[0]))
            t_trace += time.perf_counter() - t1
            bad = ~np.isfinite(L)
            if bad.any():
                n_bad += int(bad.sum())
                L = np.where(bad, 0.0, L)
            acc += np.bincount(idx, weights=L.ravel().astype(np.float64), minlength=npix * nb)
        s0 += spp_pass
    acc = acc.reshape(npix, nb)
    if settings.wavelengths == "stratified":
        cube = acc / band_counts(npix, nb, settings.spp, settings.seed)
    else:
        cube = acc / (4.0 * settings.spp / nb)
    cube = cube.reshape(h, w, nb).astype(np.float32)
    emission = np.ones(nb)
    name = "flat"
    if len(groups) == 1:
        emission, name = group_emission(scene, groups[0])
    mi, _ = _mi()
    renderer = {"name": "mitsuba", "version": str(mi.__version__), "variant": select_variant(),
                "settings": {"integrator": "path", "max_depth": scene.max_depth, "rfilter": "box",
                             "wavelength_sampling": settings.wavelengths, "denoiser": None, "clamp": None,
                             "emitter_sampling": "power", "spp": settings.spp, "seed": settings.seed,
                             "passes": passes,
                             "libllvm": _STATE.get("libllvm")}}
    stats = {"load_s": round(t_load, 4), "trace_s": round(t_trace, 4),
             "total_s": round(time.perf_counter() - t0, 4), "nonfinite_samples": n_bad,
             "mean": float(cube.mean()), "max": float(cube.max()), "min": float(cube.min())}
    return CubeResult(cube=cube, emission=np.asarray(emission, dtype=np.float64), emission_name=name,
                      renderer=renderer, stats=stats)


# Broad bands (nm) whose mean reflectance forms the RGB albedo AOV.
ALBEDO_BANDS = ((600.0, 700.0), (500.0, 600.0), (400.0, 500.0))


def render_aovs(scene: Scene, view: str, settings: RenderSettings = RenderSettings()) -> dict[str, np.ndarray]:
    """Geometry AOVs of a view, averaged over ``aov_spp`` jittered primary rays per pixel.

    albedo ``(H, W, 3)``: mean diffuse reflectance (Mitsuba's ``eval_diffuse_reflectance``) over
    600–700, 500–600, 400–500 nm (R, G, B); normal ``(H, W, 3)``: world-space shading normal
    (unit, of the hits); depth ``(H, W)``: distance from the camera along the ray in metres (0 where
    nothing is hit); mask ``(H, W)`` bool: the pixel centre ray hits geometry. float32 except mask.
    """
    tracer = _Tracer(scene, view, [], settings.resolution)
    w, h = tracer.width, tracer.height
    npix = w * h
    k = max(1, settings.aov_spp)
    rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, 0xA0F])
    pix = np.repeat(np.arange(npix, dtype=np.int64), k)
    jitter = rng.random((len(pix), 2), dtype=np.float32)
    jitter[::k] = 0.5  # the first sample of every pixel is its centre (for the mask)
    u = rng.random((len(pix), 3))
    lam = np.empty((len(pix), 4), dtype=np.float32)
    for c, (a, b) in enumerate(ALBEDO_BANDS):
        lam[:, c] = a + (b - a) * u[:, c]
    lam[:, 3] = 550.0
    out = tracer.first_hit(pix, jitter, lam)
    hit = out["hit"].reshape(npix, k)
    hitf = hit.astype(np.float64)
    nh = np.maximum(hitf.sum(axis=1), 1)
    albedo = (out["albedo"][:, :3].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1) / nh[:, None]
    normal = (out["normal"].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1)
    norm = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(norm > 0, normal / np.where(norm > 0, norm, 1), 0.0)
    depth = (out["distance"].reshape(npix, k) * hitf).sum(axis=1) / nh
    return {"albedo": albedo.reshape(h, w, 3).astype(np.float32),
            "normal": normal.reshape(h, w, 3).astype(np.float32),
            "depth": depth.reshape(h, w).astype(np.float32),
            "mask": hit[:, 0].reshape(h, w)}


def camera_meta(scene: Scene, view: str, resolution: tuple[int, int] | None = None) -> dict:
    v = scene.view(view)
    w, h = resolution or v.resolution
    return {"width": int(w), "height": int(h), "camera": {"origin": list(v.origin), "target": list(v.target),
                                                          "up": list(v.up)}, "fov": v.fov, "fov_axis": "x"}
