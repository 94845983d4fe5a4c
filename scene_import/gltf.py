"""glTF 2.0 (``.gltf`` / ``.glb``) → an illumix scene document, read with pygltflib.

What maps to what
-----------------
- **Meshes**: every triangle primitive (strips and fans are converted; points and lines are
  skipped with a warning) is written once as a PLY in object space; each node instancing it becomes
  an ``obj``-style ``ply`` shape with the node's world matrix (``transform.matrix``, row-major 4×4).
  glTF is metres, right-handed, +y up, like illumix: no change of frame. UVs are kept as they are
  (glTF's ``(0, 0)`` is the image's top-left texel, as in Mitsuba's bitmaps).
- **Cameras**: perspective cameras become views: origin = the node's world position, looking down
  its −z axis with +y up; glTF's vertical ``yfov`` (radians) becomes illumix's horizontal ``fov``
  (degrees) through ``aspectRatio`` (4:3 when absent); the resolution is 320 pixels wide at that
  aspect. Orthographic cameras are skipped with a warning. No camera: a view framing the scene.
- **Materials** (metallic-roughness PBR, with their base colour, metallic-roughness, emissive and
  normal textures): :mod:`scene_import.gltf_materials`. A primitive whose textures vary between metal
  and dielectric, or emitting and not, is written as one mesh per part.
- **Lights**: emissive materials make their shapes (or the emitting parts of them) area lights;
  ``KHR_lights_punctual`` point / spot lights (intensity in cd)
  and directional lights (illuminance in lx, travelling along the node's −z) become illumix lights.
  Their strengths are the source's photometric values × the colour's luminance ``Y``; their colours
  pick each group's CIE illuminant (:mod:`scene_import.colour_match`). ``range`` is ignored (warning).
  A file without punctual lights (viewers light glTF models with an environment) gets a constant sky
  ``sky`` of radiance 1 (D65) as a light group of its own, with a warning.
"""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path

import numpy as np

from illumix.scene.spectra import SceneError
from illumix.scene_import.builder import DEFAULT_WIDTH, SceneBuilder
from illumix.scene_import.colour_match import rgb_light
from illumix.scene_import.gltf_materials import SUPPORTED_EXT, GltfMaterial, material
from illumix.scene_import.gltf_textures import submesh
from illumix.scene_import.names import key_name

COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


class _Reader:
    """Buffers, accessors and images of one glTF file."""

    def __init__(self, gltf, path: Path) -> None:
        self.gltf, self.path, self._buffers = gltf, path, {}

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.gltf.buffers[i]
            if b.uri is None:
                data = self.gltf.binary_blob()
            elif b.uri.startswith("data:"):
                data = base64.b64decode(b.uri.split(",", 1)[1])
            else:
                from urllib.parse import unquote

                f = self.path.parent / unquote(b.uri)
                if not f.is_file():
                    raise SceneError(f"{self.path}: buffer file {b.uri!r} does not exist")
                data = f.read_bytes()
            if data is None:
                raise SceneError(f"{self.path}: buffer {i} has no data")
            self._buffers[i] = data
        return self._buffers[i]

    def view_bytes(self, i: int) -> bytes:
        bv = self.gltf.bufferViews[i]
        start = bv.byteOffset or 0
        return self.buffer(bv.buffer)[start:start + bv.byteLength]

    def accessor(self, i: int, what: str, warn) -> np.ndarray:
        """Accessor ``i`` as ``(count, width)`` float64 (normalised integers scaled to [0, 1] / [-1, 1])."""
        a = self.gltf.accessors[i]
        dt, k = np.dtype(COMPONENTS[a.componentType]).newbyteorder("<"), WIDTH[a.type]
        if a.bufferView is None or a.count == 0:
            out = np.zeros((a.count, k))
        else:
            bv = self.gltf.bufferViews[a.bufferView]
            raw = self.view_bytes(a.bufferView)
            stride = bv.byteStride or dt.itemsize * k
            off = a.byteOffset or 0
            rows = np.frombuffer(raw, dtype=np.uint8, count=(a.count - 1) * stride + dt.itemsize * k, offset=off)
            idx = (np.arange(a.count)[:, None] * stride + np.arange(dt.itemsize * k)[None, :])
            out = rows[idx].copy().view(dt).reshape(a.count, k).astype(np.float64)
        if a.normalized and dt.kind in "iu":
            out = np.maximum(out / np.iinfo(dt).max, -1.0)
        if a.sparse is not None:
            warn(f"{what}: sparse accessor {i} (morph/sparse data) is not applied; the base values are used")
        return out

    def image(self, i: int):
        from PIL import Image

        im = self.gltf.images[i]
        if im.bufferView is not None:
            data = self.view_bytes(im.bufferView)
        elif im.uri and im.uri.startswith("data:"):
            data = base64.b64decode(im.uri.split(",", 1)[1])
        else:
            from urllib.parse import unquote

            data = (self.path.parent / unquote(im.uri or "")).read_bytes()
        img = Image.open(io.BytesIO(data))
        img.load()
        return img

    def texture(self, ti, label: str, what: str, warn):
        """The PIL image of texture info ``ti`` (``label``: which of the material's textures), or None
        with a warning when it has no readable image."""
        if (ti.texCoord or 0) != 0:
            warn(f"{what}: {label} uses TEXCOORD_{ti.texCoord}; TEXCOORD_0 is used")
        if ti.extensions:
            warn(f"{what}: {label} extension(s) {', '.join(ti.extensions)} ignored")
        tex = self.gltf.textures[ti.index]
        if tex.source is None:
            warn(f"{what}: {label} has no image (extension {', '.join(tex.extensions or {}) or '?'}); ignored")
            return None
        try:
            img = self.image(tex.source)
        except Exception as exc:  # noqa: BLE001 — any unreadable image: say so, carry on without it
            warn(f"{what}: {label} image {tex.source} cannot be read ({exc}); ignored")
            return None
        if tex.sampler is not None:
            smp = self.gltf.samplers[tex.sampler]
            if (smp.wrapS or 10497) != 10497 or (smp.wrapT or 10497) != 10497:
                warn(f"{what}: texture wrap modes other than REPEAT are rendered as REPEAT")
        return img


def _local_matrix(node) -> np.ndarray:
    if node.matrix is not None and len(node.matrix) == 16:
        return np.asarray(node.matrix, dtype=float).reshape(4, 4).T  # glTF stores column-major
    t = np.eye(4)
    if node.translation is not None:
        t[:3, 3] = node.translation
    r = np.eye(4)
    if node.rotation is not None:
        x, y, z, w = node.rotation
        n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
        x, y, z, w = x / n, y / n, z / n, w / n
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    s = np.diag([*(node.scale if node.scale is not None else (1, 1, 1)), 1.0])
    return t @ r @ s


def _triangles(mode: int, idx: np.ndarray) -> np.ndarray | None:
    if mode == 4:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    if mode == 5:  # strip: alternate winding
        tris = [(idx[i], idx[i + 1], idx[i + 2]) if i % 2 == 0 else (idx[i + 1], idx[i], idx[i + 2])
                for i in range(len(idx) - 2)]
        return np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    if mode == 6:  # fan
        return np.stack([np.full(len(idx) - 2, idx[0]), idx[1:-1], idx[2:]], axis=1)
    return None


def _name(obj, kind: str, i: int) -> str:
    return getattr(obj, "name", None) or f"{kind}{i}"


def import_gltf(path: Path, b: SceneBuilder) -> str:
    """Fill ``b`` from a glTF file; returns the scene's name (see the module docstring)."""
    from pygltflib import GLTF2

    try:
        gltf = GLTF2().load(str(path))
    except Exception as exc:  # noqa: BLE001 — pygltflib raises many kinds; one line for all
        raise SceneError(f"{path}: not a readable glTF file ({type(exc).__name__}: {str(exc)[:200]})") from None
    if gltf is None:
        raise SceneError(f"{path}: not a readable glTF file")
    r = _Reader(gltf, path)
    for e in sorted(set(gltf.extensionsRequired or []) - SUPPORTED_EXT):
        b.warn(f"{path.name}: required extension {e} is not supported; what it encodes may be missing or wrong")
    for e in sorted(set(gltf.extensionsUsed or []) - SUPPORTED_EXT - set(gltf.extensionsRequired or [])):
        b.warn(f"{path.name}: extension {e} is not supported; ignored")
    lights_def = ((gltf.extensions or {}).get("KHR_lights_punctual") or {}).get("lights", [])
    materials: dict[int, GltfMaterial] = {}
    written: dict[tuple[int, int], list[tuple]] = {}
    default_mat: list[GltfMaterial] = []
    scene_i = gltf.scene if gltf.scene is not None else 0
    if not gltf.scenes:
        raise SceneError(f"{path}: the glTF file has no scene")
    stack = [(n, np.eye(4)) for n in reversed(gltf.scenes[scene_i].nodes or [])]
    while stack:
        ni, parent = stack.pop()
        node = gltf.nodes[ni]
        world = parent @ _local_matrix(node)
        nname = _name(node, "node", ni)
        stack.extend((c, world) for c in reversed(node.children or []))
        if node.skin is not None:
            b.warn(f"node {nname!r}: skinning is ignored (the bind pose is imported)")
        if node.mesh is not None:
            if abs(np.linalg.det(world[:3, :3])) < 1e-12:
                b.warn(f"node {nname!r}: its transform is singular (scale 0); skipped")
            else:
                _mesh_node(b, r, node.mesh, nname, world, materials, written, default_mat)
        if node.camera is not None:
            _camera(b, gltf.cameras[node.camera], node.camera, nname, world)
        li = ((node.extensions or {}).get("KHR_lights_punctual") or {}).get("light")
        if li is not None:
            if li >= len(lights_def):
                b.warn(f"node {nname!r}: KHR_lights_punctual light {li} does not exist; skipped")
            else:
                _light(b, lights_def[li], li, nname, world)
    if not b.lights:
        b.add_light("sky", {"type": "constant"}, None, 1.0, what="default sky")
        b.warn(f"{path.name}: no punctual lights (glTF viewers light models with an environment); added a "
               "constant sky 'sky' of radiance 1 (D65) as a light group of its own")
    return path.stem


def _mesh_node(b, r, mi, nname, world, materials, written, default_mat) -> None:
    mesh = r.gltf.meshes[mi]
    mname = _name(mesh, "mesh", mi)
    for pi, prim in enumerate(mesh.primitives):
        what = f"mesh {mname!r} primitive {pi} (node {nname!r})"
        if prim.extensions:
            b.warn(f"{what}: extension(s) {', '.join(prim.extensions)} not supported; primitive skipped")
            continue
        if prim.targets:
            b.warn(f"{what}: morph targets are ignored")
        mat = _prim_material(b, r, prim, materials, default_mat)
        if (mi, pi) not in written:
            written[(mi, pi)] = _write_parts(b, r, prim, mat, key_name(f"{mname}-{pi}"), world, what)
        parts = written[(mi, pi)]
        for suffix, rel, flat, key, emission in parts:
            doc = {"type": "ply", "filename": rel, "face_normals": flat, "material": key,
                   "transform": {"matrix": np.round(world, 12).tolist()}}
            em = None
            if emission is not None:
                xy, y = rgb_light(emission)
                em = ([mat.name, nname, mname], mat.name, xy, y) if y > 0 else None
            name = nname + (f"-{pi}" if len(mesh.primitives) > 1 else "") + (f"-{suffix}" if len(parts) > 1 else "")
            b.add_shape(name, doc, em, what=what)


def _prim_material(b, r, prim, materials, default_mat) -> GltfMaterial:
    if prim.material is None:
        if not default_mat:
            g = GltfMaterial("default", "the default material")
            g.fixed = b.add_material("default", {"kind": "diffuse", "reflectance": {"value": 0.8}})
            default_mat.append(g)
        return default_mat[0]
    if prim.material not in materials:
        materials[prim.material] = material(b, r, prim.material,
                                            lambda ti, label, what: r.texture(ti, label, what, b.warn))
    return materials[prim.material]


def _write_parts(b, r, prim, mat: GltfMaterial, stem: str, world, what: str) -> list[tuple]:
    """``[(suffix, PLY path, face normals?, material key, emission RGB or None)]``: the primitive's
    triangles in object space, one PLY per part of its material (:meth:`GltfMaterial.parts`)."""
    att = prim.attributes
    if att.POSITION is None:
        b.warn(f"{what}: no POSITION; skipped")
        return []
    pos = r.accessor(att.POSITION, what, b.warn)
    idx = (r.accessor(prim.indices, what, b.warn)[:, 0].astype(np.int64) if prim.indices is not None
           else np.arange(len(pos)))
    tris = _triangles(prim.mode if prim.mode is not None else 4, idx)
    if tris is None or len(tris) == 0:
        b.warn(f"{what}: mode {prim.mode} (points/lines) or no triangles; skipped")
        return []
    nrm = r.accessor(att.NORMAL, what, b.warn) if att.NORMAL is not None else None
    uv = r.accessor(att.TEXCOORD_0, what, b.warn) if att.TEXCOORD_0 is not None else None
    if uv is None and mat.normal:
        b.warn(f"{what}: no TEXCOORD_0, so {mat.what}'s normal map cannot apply; rendered without it")
    b.extend_bounds((world @ np.c_[pos, np.ones(len(pos))].T).T[:, :3])
    parts = mat.parts(pos, uv, tris, b.warn, what)
    out = []
    for suffix, sel, metal, emission in parts:
        p, n, t, f = (pos, nrm, uv, tris) if len(parts) == 1 else submesh(pos, nrm, uv, tris[sel])
        rel = b.write_ply(stem if len(parts) == 1 else f"{stem}-{suffix}", p, f, n, t)
        out.append((suffix, rel, nrm is None, mat.key(metal, uv is not None), emission))
    return out


def _camera(b, cam, ci, nname, world) -> None:
    what = f"camera {_name(cam, 'camera', ci)!r} (node {nname!r})"
    if cam.type != "perspective" or cam.perspective is None:
        b.warn(f"{what}: {cam.type} cameras cannot be imported; skipped")
        return
    p = cam.perspective
    aspect = float(p.aspectRatio) if p.aspectRatio else 4 / 3
    if not p.aspectRatio:
        b.warn(f"{what}: no aspectRatio; 4:3 assumed")
    hfov = math.degrees(2 * math.atan(math.tan(float(p.yfov) / 2) * aspect))
    if not 0 < hfov < 180:
        b.warn(f"{what}: horizontal field of view {hfov:.1f}° out of range; skipped")
        return
    res = (DEFAULT_WIDTH, max(1, round(DEFAULT_WIDTH / aspect)))
    b.add_view(_name(cam, "camera", ci) if cam.name else nname, world[:3, 3], -world[:3, 2], world[:3, 1], hfov, res)


def _light(b, ld: dict, li: int, nname: str, world) -> None:
    lname = ld.get("name") or nname
    what = f"light {lname!r} (node {nname!r})"
    kind = ld.get("type")
    xy, y = rgb_light(ld.get("color", [1.0, 1.0, 1.0]))
    strength = float(ld.get("intensity", 1.0)) * y
    if strength <= 0 or xy is None:
        b.warn(f"{what}: emits nothing; skipped")
        return
    if ld.get("range") is not None:
        b.warn(f"{what}: range {ld['range']:g} is ignored (light falls off with the inverse square of distance)")
    pos, fwd = world[:3, 3], world[:3, :3] @ np.array([0.0, 0.0, -1.0])
    fwd = fwd / np.linalg.norm(fwd)
    names = [lname, nname]
    if kind == "point":
        b.add_light(lname, {"type": "point", "position": pos.tolist()}, xy, strength, names, what)
    elif kind == "spot":
        spot = ld.get("spot") or {}
        outer = math.degrees(float(spot.get("outerConeAngle", math.pi / 4)))
        inner = math.degrees(float(spot.get("innerConeAngle", 0.0)))
        if outer >= 90:
            b.warn(f"{what}: outer cone {outer:.1f}° clamped to 89.9°")
            outer = 89.9
        b.add_light(lname, {"type": "spot", "position": pos.tolist(), "target": (pos + fwd).tolist(),
                            "cutoff_angle": max(outer, 1e-3), "beam_width": min(max(inner, 1e-3), max(outer, 1e-3))},
                    xy, strength, names, what)
    elif kind == "directional":
        b.add_light(lname, {"type": "directional", "direction": fwd.tolist()}, xy, strength, names, what)
    else:
        b.warn(f"{what}: light type {kind!r} is not supported; skipped")
