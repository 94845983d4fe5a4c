"""Import a Blender ``.blend`` file as an illumix :class:`~scene.model.Scene`.

:mod:`scene_import.blend_worker` reads the file in Blender's Python (:mod:`scene.blender_env`)
into ``scene.json`` plus one world-space PLY per mesh object and material; this module turns that
into a scene document and validates it (:func:`~scene.load.scene_from_dict`).

Conventions
-----------
- **Coordinates**: Blender's world frame as it is — right-handed, +Z up, one Blender unit = one
  metre (a unit scale other than 1 is warned about, not applied). Views take ``up`` from the camera's
  +Y axis, so the image is framed as in Blender.
- **Names**: shapes, lights, materials, views and groups get renderer-safe keys
  (:mod:`scene_import.names`: Blender's duplicate ``Cube.001`` → ``Cube_001``; Mitsuba reserves ``.``);
  the originals are listed in the scene's ``generator.renamed``, with one warning.
- **Light groups**: the custom property ``illumix_group`` on the object (or light data) if set, else
  the object's first collection (instances: their instancer's), else ``scene``; the world is the
  group ``world``. Every group has ``emission: flat``: a light's or emitting material's
  *colour* is replaced by the group's spectrum (a warning names each non-grey one) and only its
  magnitude is kept.
- **Emitter strengths** (per unit of the group spectrum): point and spot — intensity ``P / 4π``
  [W/sr] from Blender's power ``P`` [W] (a Blender spot has the intensity of a point light of the
  same power); sun — irradiance = its strength [W/m²]; area light — an emitting ``rectangle``/``disk``
  of radiance ``P / (π A)`` [W/(m² sr)] (``P / π`` when "normalize" is off), emitting along the light's
  −Z as in Blender; emitting materials — emission strength × the colour's largest channel; world —
  a plain Background of constant colour is a ``constant`` sky of strength × the colour's largest
  channel; any other world (Environment Texture, Sky Texture, mixes, groups) is baked by Cycles into
  an equirectangular EXR (:mod:`scene_import.blend_nodes`) and imported as an ``envmap`` light of
  strength 1 (the Background strength is in the pixels), turned into Blender's frame; a world with a
  Sky Texture makes ``world`` a ``daylight`` group.
- **Materials**: ``illumix_reflectance`` (custom property: ``"Library/Sample"`` or a bare sample name)
  names a measured reflectance from :mod:`retarget.reflectances`; otherwise the linear sRGB base
  colour is upsampled to a smooth spectrum (Jakob & Hanika 2019, under D65, 380–780 nm / 5 nm) and
  given inline. Metallic > 0.5 → ``roughconductor`` (Al, α = roughness²), transmission > 0.5 →
  ``dielectric`` (the Principled IOR), a Principled BSDF with roughness < 0.999 → ``roughplastic``
  (α = roughness², IOR; an upsampled base colour divided by
  :func:`scene.plastic_scale.plastic_diffuse_scale`, so it renders as bright as in Blender —
  Mitsuba's rough plastic loses 7–27 % of its diffuse light in the coating, the Principled BSDF
  does not), otherwise ``diffuse``. Shader nodes inside node groups are followed (values given on
  the Group node included). A base colour from an Image Texture node (UV-mapped) becomes a bitmap
  reflectance (the image × the rough-plastic factor per texel, in the cache), and a tangent-space
  Normal Map node of a UV-mapped image on the Normal input the material's ``normal_map`` (its
  strength baked in as Cycles blends it); objects without a UV map get the image's mean colour and
  no normal map instead. Whatever cannot be represented (other texture-linked
  inputs, other shader nodes, no material) is replaced by a stated value with a ``UserWarning``.
- **Cache**: the worker's output goes to ``$ILLUMIX_CACHE/blend-import/<sha256(file)[:16]>/``
  (``ILLUMIX_CACHE`` defaults to ``~/.cache/illumix``), written to a temporary directory and renamed
  into place; it is reused while the worker (``blend_worker.py`` and ``blend_nodes.py``) is unchanged.
  Linked libraries and images are not part of the key.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import numpy as np

from illumix.scene.blender_env import find_blender_python
from illumix.scene.schema import SceneError

# The name, colour and material helpers live in blend_materials; callers import some from here
# (scene_import.builder and colour_match, scene_import.import_scene, the tests).
from illumix.scene_import.blend_materials import (GREY, WAVELENGTHS, _emission, _is_grey, _Names,  # noqa: F401
                                                  _warn, material_doc, resolve_reflectance,
                                                  rgb_to_spectrum, sanitize)
from illumix.scene_import.names import Names, key_name, renamed_summary

WORKER = Path(__file__).with_name("blend_worker.py")
NODES = Path(__file__).with_name("blend_nodes.py")  # the worker's sibling module (part of the cache key)


# -- pieces of the scene ------------------------------------------------------------------------


def area_shape(li: dict, what: str, up: int = 0) -> tuple[str, np.ndarray, float]:
    """``(type, 4×4 to-world matrix, radiance)`` of an area light as a Mitsuba-style rectangle
    (``[-1, 1]²``, z = 0, normal +z) or unit disk, its +z turned onto the light's −Z
    (``up``: as for :func:`blend_materials._warn`)."""
    sx = li["size"]
    sy = li["size_y"] if li["shape"] in ("RECTANGLE", "ELLIPSE") else sx
    t = np.asarray(li["matrix"], dtype=float) @ np.diag([sx / 2, -sy / 2, -1.0, 1.0])  # a rotation by π about x
    kind = "disk" if li["shape"] in ("DISK", "ELLIPSE") else "rectangle"
    area = (math.pi if kind == "disk" else 4.0) * float(np.linalg.norm(np.cross(t[:3, 0], t[:3, 1])))
    if li.get("spread", 180.0) < 179.9:
        _warn(f"{what}: area light spread {li['spread']:.0f}° is ignored (illumix area lights are Lambertian)", up)
    power = _emission(li["color"], li["energy"], what, up)
    return kind, t, power / (math.pi * (area if li.get("normalize", True) else 1.0))


def view_doc(cam: dict, name: str, what: str) -> dict | None:
    if cam["type"] != "PERSP":
        _warn(f"{what}: {cam['type'].lower()} cameras cannot be imported; skipped")
        return None
    for bad, msg in ((any(cam["shift"]), "lens shift"), (abs(cam["pixel_aspect"] - 1) > 1e-6, "non-square pixels"),
                     (cam["dof"], "depth of field")):
        if bad:
            _warn(f"{what}: {msg} is ignored")
    m = np.asarray(cam["matrix"], dtype=float)
    origin, fwd, up = m[:3, 3], -m[:3, 2], m[:3, 1]
    return {"name": name, "origin": origin.tolist(), "target": (origin + fwd / np.linalg.norm(fwd)).tolist(),
            "up": (up / np.linalg.norm(up)).tolist(), "fov": float(cam["fov"]),
            "resolution": [int(cam["resolution"][0]), int(cam["resolution"][1])]}


def _group(item: dict, groups: dict[str, str]) -> str:
    if item.get("illumix_group"):
        g = key_name(item["illumix_group"], "group")
        groups.setdefault(g, f"custom property illumix_group = {item['illumix_group']!r}")
    elif item.get("collections"):
        g = key_name(item["collections"][0], "collection")
        groups.setdefault(g, f"Blender collection {item['collections'][0]!r}")
    else:
        g = "scene"
        groups.setdefault(g, "objects in no collection but the scene's")
    return g



def scene_doc(data: dict, cache: Path, stem: str, where: str) -> dict:
    """The scene document for the worker's ``scene.json`` ``data`` (files under ``cache``)."""
    groups: dict[str, str] = {}
    # renderer-safe keys ("Cube.001" → "Cube_001": shape and light names are Mitsuba object keys)
    mats, shape_names, light_names, views_names = Names(), Names(), Names(), Names()
    materials: dict[str, dict] = {}
    by_blender: dict[str, tuple[str | None, dict]] = {}
    for bname, info in data["materials"].items():
        mdoc = material_doc(info, f"{where}: material {bname!r}", cache)
        key = mats(bname, "material") if mdoc is not None else None
        if mdoc is not None:
            materials[key] = mdoc
        by_blender[bname] = (key, info)
    for name, why in data.get("skipped", []):
        _warn(f"{where}: object {name!r} {why}; skipped")
    if abs(data.get("unit_scale", 1.0) - 1.0) > 1e-9:
        _warn(f"{where}: unit scale {data['unit_scale']:g} is not applied; Blender units are taken as metres")
    # The helpers share the name allocators and the group table, so they run in this order (objects,
    # lights, world): it decides which duplicate gets a "-2" and the order of the light groups.
    shapes = _object_shapes(data["objects"], cache, where, by_blender, materials, mats, shape_names, groups)
    lights = _light_docs(data["lights"], where, shapes, groups, shape_names, light_names)
    kinds = _world_light(data.get("world"), where, lights, groups, light_names, cache)
    views = [v for c in data["cameras"] if (v := view_doc(c, views_names(c["name"], "camera"),
                                                          f"{where}: camera {c['name']!r}"))]
    if not views:
        raise SceneError(f"{where}: the .blend has no (perspective) camera; add one to define the view")
    used = {s["emitter"]["group"] for s in shapes if "emitter" in s} | {li["group"] for li in lights}
    if not used:
        raise SceneError(f"{where}: nothing in the .blend emits light (no lights, emitting materials or world "
                         "background); add a light")
    renamed, n = renamed_summary({"shape": shape_names, "light": light_names, "material": mats, "view": views_names})
    if n:
        _warn(f"{where}: {n} name(s) changed to renderer-safe keys (e.g. {renamed.split(';')[0].split(': ', 1)[1]}); "
              "the originals are listed in the scene's generator.renamed")
    return {"name": key_name(stem, "blend"), "description": f"imported from {data.get('file') or stem} "
            f"(Blender {data.get('blender', '?')})", "materials": materials, "shapes": shapes, "lights": lights,
            "light_groups": [{"name": g, "emission": "flat", "description": d, **kinds.get(g, {})}
                             for g, d in groups.items() if g in used],
            "views": views, **({"generator": {"name": "illumix.import", "format": "blend", "file": Path(where).name,
                                             "renamed": renamed}} if n else {})}


def _object_shapes(objects: list[dict], cache: Path, where: str, by_blender: dict, materials: dict[str, dict],
                   mats: _Names, shape_names: _Names, groups: dict[str, str]) -> list[dict]:
    """The mesh objects' ``ply`` shapes (emitting where their material emits); adds a grey diffuse to
    ``materials`` for objects without a material. Warnings as from :func:`scene_doc` (``up=1``)."""
    shapes, grey = [], None
    for ob in objects:
        what = f"{where}: object {ob['name']!r}"
        entry = {"name": shape_names(ob["name"], "shape"), "type": "ply", "filename": str(cache / ob["ply"])}
        key, info = by_blender.get(ob["material"], (None, None)) if ob["material"] else (None, None)
        if info is not None and (info.get("base_color_texture") or info.get("normal_map")) and not ob.get("uv") \
                and key is not None:
            key = _untextured(ob["material"], info, by_blender, materials, mats, what)
        if info is None:
            if grey is None:
                grey = mats("default-grey")
                materials[grey] = {"kind": "diffuse", "reflectance": {"value": 0.5}}
            _warn(f"{what} has no material; used a grey diffuse (reflectance 0.5)", 1)
            key = grey
        elif info["emission_strength"] > 0 and max(info["emission_color"]) > 0:
            s = _emission(info["emission_color"], info["emission_strength"], f"{what} (material {info['name']!r})", 1)
            if key is not None and materials[key]["kind"] == "dielectric":
                _warn(f"{what}: a dielectric cannot emit in illumix; its emission is dropped", 1)
            else:
                entry["emitter"] = {"group": _group(ob, groups), "strength": s}
        if key is None and "emitter" not in entry:
            _warn(f"{what}: material {info['name']!r} is an Emission shader that emits nothing; object skipped", 1)
            continue
        if key is not None:
            entry["material"] = key
        shapes.append(entry)
    return shapes


def _untextured(bname: str, info: dict, by_blender: dict, materials: dict[str, dict], mats: Names, what: str) -> str:
    """The variant of a textured material with the texture's mean colour (and no normal map), for an object
    without a UV map."""
    _warn(f"{what} has no UV map; material {bname!r}'s image texture is replaced by its mean colour (a normal "
          "map is dropped)", 2)
    if (bname, "untextured") not in by_blender:
        key = mats(f"{bname}-untextured", "material")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # its problems were reported with the textured variant
            materials[key] = material_doc({**info, "base_color_texture": None, "normal_map": None}, what)
        by_blender[(bname, "untextured")] = (key, info)
    return by_blender[(bname, "untextured")][0]


def _light_docs(lights_data: list[dict], where: str, shapes: list[dict], groups: dict[str, str],
                shape_names: _Names, light_names: _Names) -> list[dict]:
    """The lights; area lights become emitting shapes appended to ``shapes``. Warnings as from
    :func:`scene_doc` (``up=1``)."""
    lights = []
    for li in lights_data:
        what = f"{where}: light {li['name']!r}"
        for p in li.get("problems", []):
            _warn(f"{what}: {p}", 1)
        if li["energy"] <= 0 or max(li["color"]) <= 0:
            _warn(f"{what} emits nothing; skipped", 1)
            continue
        g = _group(li, groups)
        name = light_names(li["name"], "light")
        if li["type"] == "AREA":
            kind, t, radiance = area_shape(li, what, 1)
            shapes.append({"name": shape_names(li["name"], "light"), "type": kind, "transform": {"matrix": t.tolist()},
                           "emitter": {"group": g, "strength": radiance}})
            continue
        s = _emission(li["color"], li["energy"], what, 1)
        if li["type"] == "SUN":
            lights.append({"name": name, "type": "directional", "group": g, "strength": s,
                           "direction": li["direction"]})
            continue
        point = {"name": name, "type": "point", "group": g, "strength": s / (4 * math.pi), "position": li["position"]}
        if li["type"] == "SPOT":
            cutoff = li["spot_size"] / 2
            if cutoff >= 89.9:
                _warn(f"{what}: spot size {li['spot_size']:.0f}° is clamped to 179.8°", 1)
                cutoff = 89.9
            point.update(type="spot", target=(np.add(li["position"], li["direction"])).tolist(), cutoff_angle=cutoff,
                       beam_width=max(cutoff * (1 - li["spot_blend"]), 1e-3))
        lights.append(point)
    return lights


def _world_light(w: dict | None, where: str, lights: list[dict], groups: dict[str, str], light_names: Names,
                 cache: Path) -> dict[str, dict]:
    """Appends the world, a ``constant`` light or a baked ``envmap`` of the group ``world``, to ``lights``
    when it can be imported and emits; returns the group's extra fields (``kind: daylight`` for a Sky
    Texture). Warnings as from :func:`scene_doc` (``up=1``)."""
    if not w:
        return {}
    if w.get("envmap") and not w.get("peak", 1.0) > 0:
        _warn(f"{where}: world: its baked environment map is black; the world emits nothing", 1)
    elif w.get("envmap"):
        for p in w.get("problems", []):
            _warn(f"{where}: world: {p}", 1)
        what = " and ".join(w.get("textures") or []) or "node tree"
        _warn(f"{where}: world {what} baked by Cycles into an environment map ({w.get('bake_seconds', '?')} s) "
              f"and imported as the envmap light group 'world'", 1)
        groups["world"] = f"the world's {what}, baked to an environment map"
        lights.append({"name": light_names("world", "world"), "type": "envmap", "group": "world", "strength": 1.0,
                       "filename": str(cache / w["envmap"]), "transform": {"matrix": w["to_world"]}})
        return {"world": {"kind": "daylight"}} if w.get("sky") else {}
    for p in w.get("problems", []):
        _warn(f"{where}: world: {p}; the background is not imported", 1)
    if w.get("color") is not None and not w.get("problems"):
        s = _emission(w["color"], w["strength"], f"{where}: world background", 1)
        if s > 0:
            groups["world"] = "the world background"
            lights.append({"name": light_names("world", "world"), "type": "constant", "group": "world",
                           "strength": s})
    return {}


# -- running the worker -------------------------------------------------------------------------


def _cache_root() -> Path:
    return Path(os.environ.get("ILLUMIX_CACHE", Path.home() / ".cache" / "illumix")) / "blend-import"


def export_blend(path: Path, cache_dir: Path | None = None) -> Path:
    """The worker's output directory for ``path`` (run now unless cached); :class:`SceneError` on failure."""
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    worker_hash = hashlib.sha256(WORKER.read_bytes() + NODES.read_bytes()).hexdigest()[:16]
    out = Path(cache_dir) if cache_dir is not None else _cache_root() / digest
    done = out / "done.json"
    if done.is_file() and json.loads(done.read_text()) == {"file": digest, "worker": worker_hash}:
        return out
    if out.exists() and not (done.is_file() or (out.is_dir() and not any(out.iterdir()))):
        raise SceneError(f"{path}: cache directory {str(out)!r} exists and is not a blend-import cache; "
                         "give a new or empty directory")
    python, _ = find_blender_python()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        r = subprocess.run([python, str(WORKER), str(path.resolve()), str(tmp)], capture_output=True, text=True,
                           timeout=600)
        if r.returncode != 0 or not (tmp / "scene.json").is_file():
            lines = [ln.strip() for ln in r.stderr.splitlines() if ln.strip()]
            msg = next((ln.removeprefix("blend_worker: ") for ln in reversed(lines) if ln.startswith("blend_worker:")),
                       lines[-1] if lines else f"exit status {r.returncode}")
            raise SceneError(f"{path}: cannot import the .blend file: {msg}")
        (tmp / "done.json").write_text(json.dumps({"file": digest, "worker": worker_hash}))
        if out.exists():  # stale (another file or worker version): replace it
            old = out.with_name(f".{out.name}-old-{os.getpid()}")
            out.rename(old)
            shutil.rmtree(old, ignore_errors=True)
        try:
            tmp.rename(out)
        except OSError:  # another process got there first; its output is as good
            if not (out / "done.json").is_file():
                raise
    except subprocess.TimeoutExpired:
        raise SceneError(f"{path}: reading the .blend file took over 600 s") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def blend_doc(path: str | Path, *, cache_dir: str | Path | None = None) -> tuple[dict, Path]:
    """``(scene document, its base folder)`` of a ``.blend`` file (one scene, named after the file's
    stem): see the module docstring. :func:`scene.load.load_blend` validates it.

    ``cache_dir``: where the worker's output goes (default: the cache described above).
    Problems that have a stated substitute are ``UserWarning`` s; the rest raise :class:`SceneError`.
    """
    p = Path(path)
    if not p.is_file():
        what = "is a directory" if p.is_dir() else "does not exist"
        raise SceneError(f"blend file {str(p)!r} {what}")
    out = export_blend(p, None if cache_dir is None else Path(cache_dir))
    data = json.loads((out / "scene.json").read_text())
    return scene_doc(data, out.resolve(), p.stem, str(p)), out.resolve()


def load_blend(path: str | Path, *, cache_dir: str | Path | None = None) -> list:
    """The scene of a Blender ``.blend`` file (:func:`blend_doc`: read by Blender in a worker
    process, ``cache_dir`` its output), validated: ``[Scene]``."""
    from illumix.scene.load import scene_from_dict

    doc, base = blend_doc(path, cache_dir=cache_dir)
    return [scene_from_dict(doc, source=str(path), base=base)]
