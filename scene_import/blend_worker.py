"""Blend worker: reads a ``.blend`` file with Blender's ``bpy`` into plain data for illumix.

Runs in Blender's Python (``bpy`` 4.5 pins numpy < 2; see :mod:`scene.blender_env`) and
imports only the standard library, numpy, bpy and its sibling ``blend_nodes`` — nothing of illumix.
:mod:`scene_import.blend` runs it and turns its output into a scene::

    python blend_worker.py FILE.blend OUT_DIR     # writes OUT_DIR/scene.json and OUT_DIR/meshes/*.ply

Conventions of the output (all in Blender's world frame: right-handed, +Z up, Blender units,
which illumix takes as metres):

- **meshes**: one little-endian binary PLY per (object instance, material slot) — the evaluated
  mesh (modifiers applied, render settings: modifiers shown in render, subdivision render levels,
  render visibility), triangulated by Blender's loop triangles, in world space. Vertices carry
  Blender's corner normals (smooth/flat/sharp edges and custom normals respected); corners with the
  same position and normal (and UV) share a vertex, so flat faces get their own vertices. Objects
  whose material has an image texture or a normal map also carry their render UV map as ``u v`` with ``v`` flipped
  (``1 − v``: row 0 of an image file at ``v = 0``, Mitsuba's bitmap convention). Mirrored
  transforms keep counter-clockwise winding about the outward normal.
- **materials**: the values a Principled BSDF / Diffuse BSDF / Emission node holds — in the material's
  tree or inside its node groups (:mod:`scene_import.blend_nodes`) — colours linear (scene-linear
  sRGB primaries), and ``problems``: everything that could not be read as data (texture-linked
  inputs, other shader nodes, ignored features) with what was used instead.
- **lights**: world position, direction (the light's −Z axis), power ``energy × 2^exposure`` [W]
  (sun: irradiance [W/m²]), linear colour (× blackbody colour when a temperature is used).
- **cameras**: world matrix (columns: right, up, backward, position), horizontal field of view
  [degrees] from Blender's projection matrix (sensor fit, pixel aspect), resolution × percentage.
- **world**: the colour and strength of a plain Background node, or any other world (environment or
  sky texture, mixes, groups) baked by Cycles into ``OUT_DIR/world.exr`` (:mod:`scene_import.blend_nodes`).

Prints nothing on success; on failure one line on stderr and exit status 1.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import numpy as np
from blend_nodes import material_info, world_info  # this file's sibling (Python puts its folder on sys.path)

GEOMETRY = ("MESH", "CURVE", "SURFACE", "META", "FONT")


def _mat(m) -> np.ndarray:
    return np.array([list(row) for row in m], dtype=np.float64)


# -- meshes ------------------------------------------------------------------------------------


def write_ply(path: Path, pos: np.ndarray, nrm: np.ndarray, tris: np.ndarray, uv: np.ndarray | None = None) -> None:
    """Binary little-endian PLY: float32 ``x y z nx ny nz [u v]`` per vertex, ``uchar int`` triangle lists."""
    vert = np.concatenate([pos, nrm] + ([uv] if uv is not None else []), axis=1).astype("<f4")
    face = np.empty(len(tris), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, tris
    head = ("ply\nformat binary_little_endian 1.0\ncomment illumix blend_worker\n"
            f"element vertex {len(vert)}\n" + "".join(f"property float {c}\n" for c in
                                                     ("x", "y", "z", "nx", "ny", "nz", *("uv" * (uv is not None))))
            + f"element face {len(face)}\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as f:
        f.write(head.encode("ascii"))
        f.write(vert.tobytes())
        f.write(face.tobytes())


def mesh_parts(me, matrix: np.ndarray, with_uv: bool = False) -> dict[int, tuple]:
    """``{material index: (positions (n,3), normals (n,3), triangles (m,3), UVs (n,2) or None)}`` in world
    space; UVs (``with_uv`` and a UV map: the one active for rendering) in the bitmap convention
    ``v = 1 − v_Blender`` (row 0 of the image file at v = 0)."""
    me.calc_loop_triangles()
    nt, nl, nv = len(me.loop_triangles), len(me.loops), len(me.vertices)
    if nt == 0:
        return {}
    loops = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", loops)
    mat_idx = np.empty(nt, np.int32)
    me.loop_triangles.foreach_get("material_index", mat_idx)
    vidx = np.empty(nl, np.int32)
    me.loops.foreach_get("vertex_index", vidx)
    co = np.empty(nv * 3, np.float32)
    me.vertices.foreach_get("co", co)
    cn = np.empty(nl * 3, np.float32)
    me.corner_normals.foreach_get("vector", cn)
    a, t = matrix[:3, :3], matrix[:3, 3]
    pos = co.reshape(-1, 3).astype(np.float64) @ a.T + t
    nrm = cn.reshape(-1, 3).astype(np.float64) @ np.linalg.inv(a)  # (A^-T n) as rows
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
    nrm = nrm.astype(np.float32)
    corners = loops.reshape(-1, 3)
    if np.linalg.det(a) < 0:
        corners = corners[:, ::-1]
    layer = next((u for u in me.uv_layers if u.active_render), me.uv_layers.active) if with_uv else None
    uv = None
    if layer is not None:
        uv = np.empty(nl * 2, np.float32)
        layer.uv.foreach_get("vector", uv)
        uv = uv.reshape(-1, 2) * [1.0, -1.0] + [0.0, 1.0]
    out = {}
    for m in np.unique(mat_idx):
        c = corners[mat_idx == m]
        flat = c.ravel()
        cols = [vidx[flat, None], nrm[flat].view(np.int32)] + ([uv[flat].astype(np.float32).view(np.int32)]
                                                              if uv is not None else [])
        uniq, first, inv = np.unique(np.concatenate(cols, axis=1), axis=0, return_index=True, return_inverse=True)
        src = flat[first]
        out[int(m)] = (pos[vidx[src]], nrm[src], inv.reshape(-1, 3).astype(np.int32),
                       None if uv is None else uv[src].astype(np.float32))
    return out


# -- lights, cameras, world --------------------------------------------------------------------


def light_info(ob, m: np.ndarray) -> dict:
    li = ob.data
    color = np.array(li.color[:3], dtype=float)
    if getattr(li, "use_temperature", False):
        color = color * np.array(li.temperature_color[:3], dtype=float)
    d = {"type": li.type, "position": m[:3, 3].tolist(), "matrix": m.tolist(),
         "direction": (-m[:3, 2] / np.linalg.norm(m[:3, 2])).tolist(),
         "energy": float(li.energy) * 2.0 ** float(getattr(li, "exposure", 0.0)), "color": color.tolist(),
         "problems": []}
    if getattr(li, "use_nodes", False):
        d["problems"].append("light node tree is ignored")
    if li.type == "SPOT":
        d.update(spot_size=math.degrees(li.spot_size), spot_blend=float(li.spot_blend))
    elif li.type == "SUN":
        d["angle"] = math.degrees(li.angle)
    elif li.type == "AREA":
        d.update(shape=li.shape, size=float(li.size), size_y=float(li.size_y),
                 normalize=bool(getattr(li, "normalize", True)), spread=math.degrees(li.spread))
    return d


def camera_info(ob, render, dg) -> dict:
    """A camera's world matrix, resolution (× percentage) and horizontal field of view, the latter from
    Blender's own projection matrix (sensor fit, lens, pixel aspect: ``tan(fov/2) = 1 / P[0][0]``)."""
    cam = ob.data
    w = render.resolution_x * render.resolution_percentage // 100
    h = render.resolution_y * render.resolution_percentage // 100
    ax, ay = float(render.pixel_aspect_x), float(render.pixel_aspect_y)
    p = ob.evaluated_get(dg).calc_matrix_camera(dg, x=w, y=h, scale_x=ax, scale_y=ay)
    return {"name": ob.name, "type": cam.type, "matrix": _mat(ob.matrix_world).tolist(),
            "fov": math.degrees(2.0 * math.atan(1.0 / p[0][0])), "resolution": [w, h], "pixel_aspect": ax / ay,
            "shift": [float(cam.shift_x), float(cam.shift_y)], "sensor_fit": cam.sensor_fit,
            "lens_mm": float(cam.lens), "dof": bool(cam.dof.use_dof)}


# -- the whole file ----------------------------------------------------------------------------


def _render_visibility(bpy) -> None:
    """Make the viewport depsgraph evaluate what a render would (this copy is never saved)."""
    for coll in bpy.data.collections:
        coll.hide_viewport = coll.hide_render
    for ob in bpy.data.objects:
        ob.hide_viewport = ob.hide_render
        for md in ob.modifiers:
            md.show_viewport = md.show_render
            if md.type in ("SUBSURF", "MULTIRES"):
                md.levels = md.render_levels
    for vl in bpy.context.scene.view_layers:
        for ob in vl.objects:
            if not ob.hide_render and ob.hide_get(view_layer=vl):
                ob.hide_set(False, view_layer=vl)


def _geometry(doc: dict, ob, m: np.ndarray, record: dict, out: Path, infos: dict) -> None:
    """One PLY and object record per material slot of a geometry instance (its evaluated mesh);
    UVs where a slot's material has an image texture."""
    slots = [s.material for s in ob.material_slots]
    for mat in slots:
        if mat is not None and mat.name not in infos:
            infos[mat.name] = material_info(mat, out)
    with_uv = any(mat is not None and (infos[mat.name].get("base_color_texture") or infos[mat.name].get("normal_map"))
                  for mat in slots)
    me = ob.to_mesh()
    try:
        parts = mesh_parts(me, m, with_uv) if me is not None else {}
    finally:
        ob.to_mesh_clear()
    name = record["object"]
    if not parts:
        doc["skipped"].append([name, "has no faces"])
    for mi, (pos, nrm, tris, uv) in sorted(parts.items()):
        mat = slots[mi] if 0 <= mi < len(slots) else None
        if mat is not None and mat.name not in doc["materials"]:
            doc["materials"][mat.name] = infos[mat.name]
        ply = f"meshes/{len(doc['objects']):05d}.ply"
        write_ply(out / ply, pos, nrm, tris, uv)
        doc["objects"].append({"name": name if len(parts) == 1 else f"{name}-{mat.name if mat else mi}",
                               "ply": ply, "material": mat.name if mat else None, "uv": uv is not None,
                               "triangles": int(len(tris)), **record})


def export(bpy, out: Path) -> dict:
    sc = bpy.context.scene
    _render_visibility(bpy)
    dg = bpy.context.evaluated_depsgraph_get()
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    doc = {"file": bpy.data.filepath, "blender": bpy.app.version_string, "objects": [], "lights": [],
           "cameras": [], "materials": {}, "skipped": [],
           "unit_scale": float(sc.unit_settings.scale_length)}
    master = sc.collection
    count: dict[str, int] = {}
    infos: dict[str, dict] = {}  # material records by name, made once (their textures are saved once)
    # A curve or text object's evaluated mesh comes twice: from the object's to_mesh() and as an
    # instance of its own geometry; keep the instance.
    realized = {i.parent.original.name for i in dg.object_instances
                if i.is_instance and i.parent and i.object.original == i.parent.original}
    for inst in dg.object_instances:
        ob = inst.object
        if not inst.is_instance and ob.type != "MESH" and ob.original.name in realized:
            continue
        owner = inst.parent.original if inst.is_instance and inst.parent else ob.original
        base = owner.name if ob.original == owner else f"{owner.name}-{ob.original.name}"
        count[base] = count.get(base, 0) + 1
        name = base if count[base] == 1 else f"{base}-{count[base]}"
        colls = [c.name for c in owner.users_collection if c != master]
        group = ob.original.get("illumix_group", owner.get("illumix_group"))
        m = _mat(inst.matrix_world)
        if ob.type in GEOMETRY:
            _geometry(doc, ob, m, {"object": name, "collections": colls, "illumix_group": group}, out, infos)
        elif ob.type == "LIGHT":
            d = light_info(ob, m)
            d.update(name=name, collections=colls,
                     illumix_group=ob.original.get("illumix_group", ob.data.original.get("illumix_group", group)))
            doc["lights"].append(d)
        elif ob.type not in ("CAMERA", "EMPTY", "ARMATURE", "LIGHT_PROBE", "SPEAKER", "LATTICE"):
            doc["skipped"].append([name, f"is a {ob.type} object, which cannot be imported"])
    cams = [o for o in sc.objects if o.type == "CAMERA" and not o.hide_render]
    cams.sort(key=lambda o: (o != sc.camera, o.name))
    doc["cameras"] = [camera_info(o, sc.render, dg) for o in cams]
    doc["world"] = world_info(bpy, sc.world, out)  # last: a baked world adds a scene to this (unsaved) file
    for d in (*doc["objects"], *doc["lights"]):
        if not isinstance(d["illumix_group"], str):
            d["illumix_group"] = None
    return doc


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: blend_worker.py FILE.blend OUT_DIR", file=sys.stderr)
        return 2
    blend, out = Path(argv[0]), Path(argv[1])
    sys.stdout.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)  # Blender logs to stdout; the caller wants errors only
    try:
        import bpy

        try:
            bpy.ops.wm.open_mainfile(filepath=str(blend.resolve()), load_ui=False)
        except RuntimeError as exc:
            msg = " ".join(str(exc).split())
            raise RuntimeError(f"cannot open {blend}: {msg}") from None
        doc = export(bpy, out)
        (out / "scene.json").write_text(json.dumps(doc, indent=1))
    except Exception as exc:  # one line for the caller, whatever went wrong
        print(f"blend_worker: {type(exc).__name__}: {' '.join(str(exc).split())}"[:1000], file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
