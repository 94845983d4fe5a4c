"""Blender shader node trees as plain data, for the blend worker (:mod:`scene_import.blend_worker`).

Runs in Blender's Python beside the worker (it imports this file as ``blend_nodes``); it never
imports ``bpy`` itself — the worker hands it Blender's objects — and uses only the standard library
and numpy.

- **Links through groups**: an input is traced upstream through Reroute nodes, into Group nodes (to
  the socket of the group's active Group Output) and back out of a group's Group Input (to the
  instancing Group node's own input), so a Principled BSDF or Emission inside a node group, with its
  values given on the Group node, reads like one in the material's own tree. Muted links are skipped.
- **Materials** (:func:`material_info`): the values a Principled BSDF / Diffuse BSDF / Emission node
  holds (through groups), colours linear, and ``problems``: what could not be read as data. A base
  colour driven by an Image Texture node (flat projection, UV coordinates) is saved as
  ``textures/NNN.png`` (8-bit sRGB, the file's own orientation: row 0 at the image's top) and recorded
  with its mean linear colour (``base_color_texture``); a tangent-space Normal Map node of such an
  image on the BSDF's Normal input is saved the same way with its strength (``normal_map``).
- **World** (:func:`world_info`): a plain Background of constant colour and strength is returned as
  such; anything else (an Environment Texture, a Sky Texture, mixes, groups) is *baked*: Cycles
  renders the world alone through an equirectangular panorama camera into ``world.exr`` (scene-linear
  Rec. 709, strength included), which illumix uses as an ``envmap`` light. The bake camera looks up
  +Z at the image's top row; its columns run from −Y (u = 0) through −X, +Y, +X (Mitsuba's envmap
  frame rotated by :data:`ENVMAP_TO_WORLD`).
"""

from __future__ import annotations

import math
import time

import numpy as np

BSDFS = ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfDiffuse")
CONSTANTS = ("ShaderNodeRGB", "ShaderNodeValue")
#: Mitsuba envmap's local frame (+y up, u = 0 towards −z) → Blender's world (+Z up) for a baked world:
#: local x → −X, local y → +Z, local z → +Y (a proper rotation)
ENVMAP_TO_WORLD = [[-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
BAKE_SAMPLES = 64  # per pixel for a Sky Texture (its sun disc covers about half a pixel at 512 × 256); ¼ else


# -- links ------------------------------------------------------------------------------------


def _active_output(tree, idname: str):
    outs = [n for n in tree.nodes if n.bl_idname == idname]
    return next((n for n in outs if getattr(n, "is_active_output", False)), outs[0] if outs else None)


def source(sock, ctx: tuple = ()):
    """``(node, output socket, ctx)`` feeding input ``sock``, or ``(None, socket, ctx)`` when nothing
    does — that socket's ``default_value`` applies (the Group node's own input for a group input).
    ``ctx``: the Group nodes the walk is inside, innermost last."""
    for _ in range(256):  # a cycle in a broken file ends here rather than hanging
        links = [lk for lk in sock.links if not getattr(lk, "is_muted", False)]
        if not links:
            return None, sock, ctx
        node, out = links[0].from_node, links[0].from_socket
        if node.bl_idname == "NodeReroute":
            sock = node.inputs[0]
        elif node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
            gout = _active_output(node.node_tree, "NodeGroupOutput")
            inner = next((s for s in gout.inputs if s.identifier == out.identifier), None) if gout else None
            if inner is None:
                return node, out, ctx
            sock, ctx = inner, (*ctx, node)
        elif node.bl_idname == "NodeGroupInput" and ctx:
            outer = next((s for s in ctx[-1].inputs if s.identifier == out.identifier), None)
            if outer is None:
                return node, out, ctx
            sock, ctx = outer, ctx[:-1]
        else:
            return node, out, ctx
    return None, sock, ctx


def upstream(sock, ctx: tuple = ()) -> list:
    """``(node, ctx)`` of every node feeding ``sock``, breadth first, through groups (:func:`source`)."""
    seen, queue, out = set(), [(sock, ctx)], []
    while queue:
        s, c = queue.pop(0)
        node, _, c2 = source(s, c)
        if node is None or (node.as_pointer(), tuple(g.as_pointer() for g in c2)) in seen:
            continue
        seen.add((node.as_pointer(), tuple(g.as_pointer() for g in c2)))
        out.append((node, c2))
        queue += [(i, c2) for i in node.inputs]
    return out


def _plain(raw):
    return [float(x) for x in raw][:3] if hasattr(raw, "__len__") else float(raw)


def value(node, socket: str, ctx: tuple, problems: list, what: str):
    """An input's value: its own (or a Group node's, for a group input), or a constant RGB/Value
    node's; a problem naming the node when something else drives it."""
    s = node.inputs[socket]
    src, sock, _ = source(s, ctx)
    if src is None:
        return _plain(sock.default_value)
    if src.bl_idname in CONSTANTS:
        return _plain(src.outputs[0].default_value)  # both have one output
    val = _plain(s.default_value)
    shown = [round(x, 3) for x in val] if isinstance(val, list) else round(val, 3)
    problems.append(f"{what} '{socket}' is linked to a {src.bl_label} node ({src.name!r}), which "
                    f"cannot be imported; used the input's unlinked value {shown}")
    return val


# -- materials ---------------------------------------------------------------------------------


def image_texture(node, socket: str, ctx: tuple, out_dir, probs: list, what: str) -> dict | None:
    """``{"file", "mean"}`` of the Image Texture driving ``node``'s ``socket`` (module docstring), or None
    when it is driven otherwise (:func:`value` then reports it)."""
    src, out, c2 = source(node.inputs[socket], ctx)
    if src is None or src.bl_idname != "ShaderNodeTexImage" or src.image is None or out.name != "Color":
        return None
    vec, vout, _ = source(src.inputs["Vector"], c2)
    if (vec is not None and not (vec.bl_idname in ("ShaderNodeUVMap", "ShaderNodeTexCoord") and vout.name == "UV")) \
            or src.projection != "FLAT" or len(src.image.pixels) == 0:  # (reading pixels loads the image)
        return None
    img = src.image
    if src.extension != "REPEAT":
        probs.append(f"{what} '{socket}': image {img.name!r} extension {src.extension} is rendered as REPEAT")
    if vec is not None and vec.bl_idname == "ShaderNodeUVMap" and vec.uv_map:
        probs.append(f"{what} '{socket}': UV map {vec.uv_map!r} requested; the mesh's render UV map is used")
    if img.colorspace_settings.name != "sRGB":
        probs.append(f"{what} '{socket}': image {img.name!r} in colour space {img.colorspace_settings.name!r} "
                     "is read as sRGB")
    px = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(-1, img.channels)[:, :3].astype(np.float64)
    if not img.is_float:  # byte images hold their sRGB codes; float ones are linear already
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return {"file": _save_image(img, out_dir), "mean": rgb.mean(axis=0).tolist(), "image": img.name}


def _save_image(img, out_dir) -> str:
    """Save a Blender image as ``textures/NNN.png`` under ``out_dir``; its path relative to ``out_dir``."""
    folder = out_dir / "textures"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{len(list(folder.glob('*.png'))):03d}.png"
    img.file_format = "PNG"  # this copy of the file is never saved
    img.save(filepath=str(path))
    return f"textures/{path.name}"


def normal_map(node, ctx: tuple, out_dir, probs: list) -> dict | None:
    """``{"file", "strength"}`` of a tangent-space Normal Map node fed by a UV-mapped Image Texture on the
    BSDF's Normal input, or None (a problem names anything else linked there)."""
    src, _, c2 = source(node.inputs["Normal"], ctx)
    if src is None:
        return None
    if src.bl_idname == "ShaderNodeNormalMap" and src.space == "TANGENT":
        img_node, out, c3 = source(src.inputs["Color"], c2)
        vec = source(img_node.inputs["Vector"], c3)[0] if img_node is not None and "Vector" in img_node.inputs else None
        if (img_node is not None and img_node.bl_idname == "ShaderNodeTexImage" and img_node.image is not None
                and out.name == "Color" and vec is None and len(img_node.image.pixels) > 0):
            if img_node.image.colorspace_settings.name not in ("Non-Color", "Raw", "Linear"):
                probs.append(f"normal map image {img_node.image.name!r} is in colour space "
                             f"{img_node.image.colorspace_settings.name!r}; its stored values are used as vectors")
            strength = value(src, "Strength", c2, probs, "Normal Map")
            return {"file": _save_image(img_node.image, out_dir), "strength": float(strength),
                    "image": img_node.image.name}
    probs.append(f"'Normal' is driven by a {src.bl_label} node ({src.name!r}), which cannot be imported "
                 "(only a tangent-space Normal Map of a UV-mapped image can); ignored")
    return None


def material_info(mat, out_dir=None) -> dict:
    """Plain values of a Blender material (see the worker's module docstring)."""
    d = {"name": mat.name, "shader": None, "base_color": [0.8, 0.8, 0.8], "roughness": 0.5,
         "metallic": 0.0, "transmission": 0.0, "ior": 1.5, "emission_color": [0.0, 0.0, 0.0],
         "emission_strength": 0.0, "illumix_reflectance": mat.get("illumix_reflectance"), "problems": []}
    probs = d["problems"]
    if not isinstance(d["illumix_reflectance"], str):
        d["illumix_reflectance"] = None
    if not mat.use_nodes or mat.node_tree is None:
        d.update(base_color=list(mat.diffuse_color)[:3], roughness=float(mat.roughness),
                 metallic=float(mat.metallic))
        probs.append("uses no shader nodes; used its viewport display colour, roughness and metallic")
        return d
    outs = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
            and n.target in ("ALL", "CYCLES")]
    out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
    surf = source(out.inputs["Surface"])[0] if out is not None else None
    if surf is None:
        probs.append("has no shader connected to a Material Output's Surface")
        return d
    nodes = upstream(out.inputs["Surface"])
    bsdf = next(((n, c) for n, c in nodes if n.bl_idname in BSDFS), None)
    emit = next(((n, c) for n, c in nodes if n.bl_idname == "ShaderNodeEmission"), None)
    if surf.bl_idname not in (*BSDFS, "ShaderNodeEmission"):
        used = " and ".join(f"the {n.bl_label} node {n.name!r}" for n, _ in (x for x in (bsdf, emit) if x)) or "nothing"
        probs.append(f"surface is a {surf.bl_label} node ({surf.name!r}), which cannot be imported; used {used}")
    if bsdf is None and emit is None:
        probs.append("has no Principled BSDF, Diffuse BSDF or Emission node")
        return d
    _bsdf_values(d, bsdf, probs, out_dir)
    if emit is not None:
        d["emission_color"] = value(emit[0], "Color", emit[1], probs, "Emission")
        d["emission_strength"] = value(emit[0], "Strength", emit[1], probs, "Emission")
    return d


def _bsdf_values(d: dict, bsdf, probs: list, out_dir) -> None:
    if bsdf is None:
        d["shader"] = "emission"
        return
    node, ctx = bsdf
    colour = "Base Color" if node.bl_idname == "ShaderNodeBsdfPrincipled" else "Color"
    tex = image_texture(node, colour, ctx, out_dir, probs, "input") if out_dir is not None else None
    if tex is not None:
        d["base_color_texture"], d["base_color"] = tex, tex["mean"]
    d["normal_map"] = normal_map(node, ctx, out_dir, probs) if out_dir is not None else None
    if node.bl_idname == "ShaderNodeBsdfPrincipled":
        d["shader"] = "principled"
        for key, sock in ((("base_color", "Base Color"),) if tex is None else ()) + (
                          ("roughness", "Roughness"), ("metallic", "Metallic"),
                          ("transmission", "Transmission Weight"), ("ior", "IOR"), ("emission_color", "Emission Color"),
                          ("emission_strength", "Emission Strength")):
            d[key] = value(node, sock, ctx, probs, "input")
        for sock, bad in (("Alpha", lambda v: v < 1), ("Subsurface Weight", lambda v: v > 0),
                          ("Coat Weight", lambda v: v > 0), ("Sheen Weight", lambda v: v > 0)):
            src, s, _ = source(node.inputs[sock], ctx)
            if src is not None or bad(s.default_value):
                probs.append(f"'{sock}' is not imported (ignored)")
    else:
        d["shader"] = "diffuse"
        if tex is None:
            d["base_color"] = value(node, "Color", ctx, probs, "input")
        d["roughness"] = 1.0


# -- world -------------------------------------------------------------------------------------


def world_info(bpy, world, out_dir) -> dict | None:
    """The world as a constant background (``color``, ``strength``) or a baked ``envmap`` (module docstring)."""
    if world is None:
        return None
    if not world.use_nodes or world.node_tree is None:
        return {"color": list(world.color)[:3], "strength": 1.0, "problems": []}
    out = _active_output(world.node_tree, "ShaderNodeOutputWorld")
    bg, _, ctx = source(out.inputs["Surface"]) if out is not None else (None, None, ())
    if bg is None:
        return None
    if bg.bl_idname == "ShaderNodeBackground" and all(
            (s := source(bg.inputs[k], ctx)[0]) is None or s.bl_idname in CONSTANTS for k in ("Color", "Strength")):
        probs: list[str] = []
        return {"color": value(bg, "Color", ctx, probs, "world Background"),
                "strength": value(bg, "Strength", ctx, probs, "world Background"), "problems": probs}
    nodes = [n for n, _ in upstream(out.inputs["Surface"])]
    kinds = {n.bl_idname for n in nodes}
    d = {"color": None, "strength": 1.0, "envmap": "world.exr", "to_world": ENVMAP_TO_WORLD, "problems": [],
         "sky": "ShaderNodeTexSky" in kinds, "textures": sorted({n.bl_label for n in nodes if "Tex" in n.bl_idname})}
    if "ShaderNodeLightPath" in kinds:
        d["problems"].append("a Light Path node makes the world differ by ray type; the world as the camera "
                             "sees it is baked")
    envs = [n.image for n in nodes if n.bl_idname == "ShaderNodeTexEnvironment" and n.image is not None]
    width = min(max([512, *(int(i.size[0]) for i in envs)]), 2048)
    t0 = time.time()
    try:
        bake_world(bpy, world, out_dir / d["envmap"], width, BAKE_SAMPLES if d["sky"] else BAKE_SAMPLES // 4)
    except Exception as exc:  # noqa: BLE001 — e.g. a bpy without Cycles: the rest of the file still imports
        why = (f"baking its {' and '.join(d['textures']) or 'node tree'} with Cycles failed "
               f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})")
        return {"color": None, "strength": 0.0, "problems": [why]}
    d["bake_seconds"] = round(time.time() - t0, 2)
    img = bpy.data.images.load(str(out_dir / d["envmap"]))
    px = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(px)
    d["peak"] = float(px.reshape(-1, img.channels)[:, :3].max())  # 0: a black world emits nothing
    return d


def bake_world(bpy, world, path, width: int, samples: int) -> None:
    """Render ``world`` alone (no objects) into an equirectangular float EXR ``width × width/2`` at ``path``
    (``samples`` per pixel, box filter: each pixel is the world's mean over its solid angle)."""
    sc = bpy.data.scenes.new("illumix_world_bake")
    sc.world = world
    cam = bpy.data.cameras.new("illumix_world_bake")
    cam.type = "PANO"
    cam.panorama_type = "EQUIRECTANGULAR"
    ob = bpy.data.objects.new("illumix_world_bake", cam)
    ob.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looks along +Y: +Z at the top row (module docstring)
    sc.collection.objects.link(ob)
    sc.camera = ob
    r = sc.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, width // 2, 100
    r.film_transparent = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "32"
    r.filepath = str(path)
    sc.cycles.samples = samples
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False  # a pixel the sun disc covers partly must keep sampling
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.seed = 0
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.exposure = 0.0
    bpy.ops.render.render(write_still=True, scene=sc.name)
