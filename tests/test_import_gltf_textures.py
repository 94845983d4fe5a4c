"""glTF metallic-roughness, emissive and normal textures (:mod:`scene_import.gltf_materials`): files the test
writes itself in the shapes real models have (DamagedHelmet: a UV-mapped mesh with baseColor,
metallicRoughness (B = metal, G = roughness), emissive and normal PNG maps, no lights), checked against
the maps as painted — which triangles are metal or emit, what roughness and colour each part gets — and
rendered tiny: the model is mostly lit surface, not emitter, at the brightness a sky of radiance 1 gives.
A normal map bends shading the way glTF means (green = +v up the image): checked against Lambert's cosine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from illumix.scene.load import scene_from_dict
from illumix.scene_import import import_scene
from illumix.scene_import.colour_match import srgb_decode

N = 64  # texture size (texels)
METAL_V = 0.3  # texels with v < 0.3 (the image's top rows: the sphere's upper cap) are metal
EMIT_BOX = (0.44, 0.56, 0.44, 0.56)  # u0, u1, v0, v1 of the emissive patch
EMIT_SRGB = (255, 128, 0)
METAL_SRGB, PAINT_SRGB = 200, (150, 40, 30)
G_METAL, G_PAINT = 153, 77  # roughness texels (0.6, 0.302)


def _png(path, rgb: np.ndarray):
    from PIL import Image

    Image.fromarray(rgb.astype(np.uint8), "RGB").save(path)
    return path.name


def _maps(folder):
    """baseColor, metallicRoughness, emissive and normal PNGs painted by the constants above."""
    v = (np.arange(N)[:, None] + 0.5) / N * np.ones((1, N))
    u = np.ones((N, 1)) * (np.arange(N)[None, :] + 0.5) / N
    metal = v < METAL_V
    base = np.where(metal[..., None], METAL_SRGB, np.array(PAINT_SRGB))
    mr = np.zeros((N, N, 3))
    mr[..., 1] = np.where(metal, G_METAL, G_PAINT)
    mr[..., 2] = np.where(metal, 255, 0)
    u0, u1, v0, v1 = EMIT_BOX
    box = (u >= u0) & (u < u1) & (v >= v0) & (v < v1)
    em = np.where(box[..., None], np.array(EMIT_SRGB), 0)
    nrm = np.broadcast_to(np.array([128, 128, 255]), (N, N, 3))
    return [_png(folder / f"{k}.png", a) for k, a in (("base", base), ("mr", mr), ("em", em), ("nrm", nrm))]


def _sphere(n_lat=24, n_lon=48):
    """A UV sphere of radius 1: u = longitude / 2π, v = polar angle / π (v = 0 at +y, the image's top);
    the middle of the map (u = ½) faces the camera on +z."""
    th = np.linspace(0, math.pi, n_lat + 1)
    ph = np.linspace(0, 2 * math.pi, n_lon + 1)
    t, p = np.meshgrid(th, ph, indexing="ij")
    pos = np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], -1).reshape(-1, 3)  # u = ½ faces +z
    uv = np.stack([p / (2 * math.pi), t / math.pi], -1).reshape(-1, 2)
    i = np.arange(n_lat)[:, None] * (n_lon + 1) + np.arange(n_lon)[None, :]
    a, b, c, d = i, i + n_lon + 1, i + n_lon + 2, i + 1
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    tris = tris[np.linalg.norm(np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]]),
                               axis=1) > 1e-9]
    return pos.astype(np.float32), pos.astype(np.float32), uv.astype(np.float32), tris.astype(np.uint32)


def _quad(x0: float):
    pos = np.array([[x0, -1, 0], [x0 + 2, -1, 0], [x0 + 2, 1, 0], [x0, 1, 0]], np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # u → +x, v = 0 at the top (+y)
    return pos, np.tile(np.float32([0, 0, 1]), (4, 1)), uv, np.array([[0, 1, 2], [0, 2, 3]], np.uint32)


def _gltf(path, meshes, materials, images, nodes_extra=(), lights=(), cam_z=3.2, yfov=0.9):
    """A glTF file: one node per ``(mesh arrays, material index)``, a camera on +z looking down −z."""
    import pygltflib as g

    blob, views, acc, gm = b"", [], [], []
    for (pos, nrm, uv, tris), mat in meshes:
        ids = []
        for arr, typ, ct in ((pos, "VEC3", 5126), (nrm, "VEC3", 5126), (uv, "VEC2", 5126),
                             (tris.ravel(), "SCALAR", 5125)):
            data = np.ascontiguousarray(arr).tobytes()
            views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data)))
            extra = {"min": pos.min(0).tolist(), "max": pos.max(0).tolist()} if arr is pos else {}
            acc.append(g.Accessor(bufferView=len(views) - 1, componentType=ct, count=len(arr), type=typ, **extra))
            ids.append(len(acc) - 1)
            blob += data + b"\0" * (-len(data) % 4)
        gm.append(g.Mesh(primitives=[g.Primitive(attributes=g.Attributes(POSITION=ids[0], NORMAL=ids[1],
                                                                          TEXCOORD_0=ids[2]), indices=ids[3],
                                                 material=mat)]))
    nodes = [g.Node(name=f"Obj.{i:03d}", mesh=i) for i in range(len(meshes))]
    nodes.append(g.Node(name="Cam", camera=0, translation=[0, 0, cam_z]))
    nodes += list(nodes_extra)
    doc = g.GLTF2(asset=g.Asset(version="2.0"), scene=0, scenes=[g.Scene(nodes=list(range(len(nodes))))], nodes=nodes,
                  meshes=gm, materials=materials, textures=[g.Texture(source=i) for i in range(len(images))],
                  images=[g.Image(uri=u) for u in images], accessors=acc, bufferViews=views,
                  buffers=[g.Buffer(byteLength=len(blob))],
                  cameras=[g.Camera(type="perspective", perspective=g.Perspective(yfov=yfov, aspectRatio=4 / 3,
                                                                                  znear=0.01))])
    if lights:
        doc.extensionsUsed = ["KHR_lights_punctual"]
        doc.extensions = {"KHR_lights_punctual": {"lights": list(lights)}}
    doc.set_binary_blob(blob)
    doc.convert_buffers(g.BufferFormat.DATAURI)
    doc.save_json(str(path))
    return path


def _helmet(tmp_path):
    import pygltflib as g

    _maps(tmp_path)
    mat = g.Material(name="Helmet.001", emissiveFactor=[1.0, 1.0, 1.0], emissiveTexture=g.TextureInfo(index=2),
                     normalTexture=g.NormalMaterialTexture(index=3),
                     pbrMetallicRoughness=g.PbrMetallicRoughness(baseColorTexture=g.TextureInfo(index=0),
                                                                 metallicRoughnessTexture=g.TextureInfo(index=1)))
    return _gltf(tmp_path / "helmet.gltf", [(_sphere(), 0)], [mat], ["base.png", "mr.png", "em.png", "nrm.png"])


@pytest.fixture(scope="module")
def helmet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("helmet")
    doc, warns = import_scene(_helmet(folder), folder / "out")
    return doc, warns, scene_from_dict(doc, source="imported", base=folder / "out"), folder / "out"


def _ply(path):
    import trimesh

    m = trimesh.load(path, process=False)
    return np.asarray(m.vertices), np.asarray(m.faces), m.metadata["_ply_raw"]["vertex"]["data"]


def test_metal_and_paint_parts_follow_the_metalness_map(helmet):
    _, warns, scene, out = helmet
    shapes = {s.name: s for s in scene.shapes}
    assert set(shapes) == {"Obj_000-dielectric", "Obj_000-metal", "Obj_000-dielectric-emit"}
    metal = scene.materials[shapes["Obj_000-metal"].material]
    paint = scene.materials[shapes["Obj_000-dielectric"].material]
    assert metal.kind == "roughconductor" and paint.kind == "roughplastic"
    # roughness: each part's texels' G, squared (the map is uniform within each class)
    assert metal.alpha == pytest.approx((G_METAL / 255) ** 2) and paint.alpha == pytest.approx((G_PAINT / 255) ** 2)
    # the metal's colour is its texels' base colour (a grey: a constant spectrum)
    assert metal.specular_reflectance.value == pytest.approx(float(srgb_decode(METAL_SRGB / 255)), abs=1e-4)
    assert paint.reflectance.file.endswith(".png")
    # every metal vertex lies on the cap the map paints (polar angle < 0.3 π), up to one triangle row
    band = math.cos(METAL_V * math.pi)
    pos, _, _ = _ply(out / shapes["Obj_000-metal"].filename)
    assert pos[:, 1].min() >= math.cos((METAL_V + 1 / 24) * math.pi) - 1e-6
    pos, _, _ = _ply(out / shapes["Obj_000-dielectric"].filename)
    assert pos[:, 1].max() <= math.cos((METAL_V - 1 / 24) * math.pi) + 1e-6 and pos[:, 1].min() < band
    assert any("metallicRoughnessTexture" in w and "metal" in w for w in warns)


def test_only_the_emissive_patch_emits(helmet):
    _, warns, scene, out = helmet
    shapes = {s.name: s for s in scene.shapes}
    em = shapes["Obj_000-dielectric-emit"]
    assert [s.name for s in scene.shapes if s.emitter is not None] == [em.name]
    _, faces, data = _ply(out / em.filename)
    uv = np.stack([data["u"], data["v"]], -1)[faces].mean(axis=1)  # triangle centroids' UVs
    u0, u1, v0, v1 = EMIT_BOX
    assert np.all((uv[:, 0] > u0 - 0.05) & (uv[:, 0] < u1 + 0.05) & (uv[:, 1] > v0 - 0.05) & (uv[:, 1] < v1 + 0.05))
    full = np.array(srgb_decode(np.array(EMIT_SRGB) / 255)) @ [0.2126, 0.7152, 0.0722]  # Y of the texel colour
    assert 0.4 * full <= em.emitter.strength <= full * 1.0001  # edge triangles average in black texels
    # its group: the patch's orange (not a CIE white) → a blackbody at its CCT, said in a warning
    assert scene.group(em.emitter.group).emission.startswith(("blackbody:", "A"))
    assert any("emissiveTexture" in w and "triangles emit" in w for w in warns)
    # no punctual lights: a sky of radiance 1 lights the model, in a group of its own
    assert [(li.name, li.type, li.strength) for li in scene.lights] == [("sky", "constant", 1.0)]
    assert scene.lights[0].group != em.emitter.group


def test_normal_map_is_baked_with_its_scale(tmp_path):
    from PIL import Image

    from illumix.scene_import.gltf_textures import normal_png

    c = np.zeros((2, 2, 3), np.uint8) + np.array([128, 128, 255], np.uint8)
    c[0, 0] = (200, 100, 220)
    data, _ = normal_png(Image.fromarray(c, "RGB"), 2.0)
    (tmp_path / "n.png").write_bytes(data)
    got = np.asarray(Image.open(tmp_path / "n.png"), dtype=float) / 255 * 2 - 1
    n = np.array([200, 100, 220]) / 255 * 2 - 1
    n[:2] *= 2
    assert got[0, 0] == pytest.approx(n / np.linalg.norm(n), abs=0.01)
    assert got[1, 1] == pytest.approx([0, 0, 1], abs=0.01)


def test_helmet_renders_lit_not_glowing(helmet):
    pytest.importorskip("mitsuba")
    from illumix.renderer_jobs.mitsuba.aovs import render_aovs
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    doc, _, _, out = helmet
    doc = {**doc, "views": [{**doc["views"][0], "resolution": [48, 36]}]}
    scene = scene_from_dict(doc, source="imported", base=out)
    (view,) = scene.view_names if hasattr(scene, "view_names") else [v.name for v in scene.views]
    assert scene.materials[next(s.material for s in scene.shapes if s.name == "Obj_000-dielectric")].normal_map
    aov = render_aovs(scene, view, RenderSettings(spp=8))
    valid = aov["mask"] & ~aov["emitter"]
    # a lit sphere (27 % of the frame) with a small glowing patch: an all-emitter import had no valid pixel
    assert valid.mean() > 0.15 and 0 < aov["emitter"].sum() < 0.3 * aov["mask"].sum()
    sky = next(li.group for li in scene.lights if li.type == "constant")
    cube = render_cube(scene, view, sky, RenderSettings(spp=8)).cube
    lum = cube[valid].mean(axis=1)
    # a sky of radiance 1 (flat) on a convex object: reflected radiance ≤ 1, paint (albedo ~0.05–0.2) and
    # grey metal (F0 0.58) well above black
    assert 0.02 < float(np.median(lum)) < 1.0 and float(lum.max()) < 1.5


def test_normal_map_tilts_shading_towards_green(tmp_path):
    """Two quads facing +z under a distant light from +y (45°): the right one's normal map tilts the normal
    30° towards green = the image's up = +y, so it is lit at cos 15° instead of cos 45°."""
    pytest.importorskip("mitsuba")
    import pygltflib as g

    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    t = math.radians(30)
    c = np.round((np.array([0, math.sin(t), math.cos(t)]) + 1) * 127.5)
    _png(tmp_path / "tilt.png", np.broadcast_to(c, (8, 8, 3)))
    _png(tmp_path / "white.png", np.full((8, 8, 3), 200))
    pbr = g.PbrMetallicRoughness(baseColorTexture=g.TextureInfo(index=1), metallicFactor=0.0, roughnessFactor=1.0)
    mats = [g.Material(name="Flat", pbrMetallicRoughness=pbr),
            g.Material(name="Tilted", pbrMetallicRoughness=pbr, normalTexture=g.NormalMaterialTexture(index=0))]
    phi = -math.pi / 4  # the light's −z turned to (0, −sin 45°, −cos 45°)
    sun = g.Node(name="SunNode", rotation=[math.sin(phi / 2), 0, 0, math.cos(phi / 2)],
                 extensions={"KHR_lights_punctual": {"light": 0}})
    path = _gltf(tmp_path / "tilt.gltf", [(_quad(-2.2), 0), (_quad(0.2), 1)], mats, ["tilt.png", "white.png"],
                 nodes_extra=[sun], lights=[{"name": "Sun", "type": "directional", "intensity": 1.0}], cam_z=4.0)
    doc, _ = import_scene(path, tmp_path / "out")
    doc["views"][0]["resolution"] = [48, 36]
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    cube = render_cube(scene, scene.views[0].name, scene.lights[0].group, RenderSettings(spp=8)).cube
    lum = cube.mean(axis=2)
    left, right = lum[14:22, 8:16].mean(), lum[14:22, 32:40].mean()  # inside each quad's image
    want = math.cos(math.radians(15)) / math.cos(math.radians(45))  # 1.366; the mirrored convention gives 0.37
    assert right / left == pytest.approx(want, rel=0.04)


def test_normal_map_field_is_validated(tmp_path):
    from illumix.scene.spectra import SceneError

    doc = {"name": "s", "materials": {"m": {"kind": "diffuse", "reflectance": {"value": 0.5},
                                            "normal_map": {"file": "bumps.jpg"}}},
           "shapes": [{"name": "q", "type": "rectangle", "material": "m"}],
           "lights": [{"name": "sky", "type": "constant", "group": "sky", "strength": 1.0}],
           "light_groups": [{"name": "sky"}], "views": [{"name": "v", "origin": [0, 0, 3], "target": [0, 0, 0]}]}
    with pytest.raises(SceneError, match="normal map 'bumps.jpg': give an 8-bit RGB PNG"):
        scene_from_dict(doc, source="t", base=tmp_path)
    doc["materials"]["m"]["normal_map"] = {"file": "bumps.png", "scale": [2, 2]}
    with pytest.raises(SceneError, match="file 'bumps.png' does not exist"):  # checked before anything renders
        scene_from_dict(doc, source="t", base=tmp_path)
    from PIL import Image

    Image.new("RGB", (4, 4), (128, 128, 255)).save(tmp_path / "bumps.png")
    assert scene_from_dict(doc, source="t", base=tmp_path).materials["m"].normal_map.scale == (2, 2)
