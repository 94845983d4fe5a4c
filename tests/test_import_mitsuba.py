"""Issue 39, Mitsuba XML that real files use: ``<include>`` (relative to the including file, nested,
cycles refused), ``<path>`` search folders, ``serialized`` meshes (a file built here byte by byte from
the format's specification), legacy 0.5 files upgraded (or refused clearly); and an import with
nothing renderable exits 2 with one line, for every importer."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from cli_testutil import run_cli
from illumix.scene.load import scene_from_dict
from illumix.scene.schema import SceneError, rotation_matrix
from illumix.scene_import import import_scene
from test_cli_spectra import assert_one_line_error

LIGHT = '<emitter type="point" id="bulb"><point name="position" x="0" y="3" z="0"/></emitter>'
QUAD_PLY = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")


def write_serialized(path, meshes) -> None:
    """Mitsuba's ``.serialized`` format (version 4): per mesh ``uint16 0x041C, uint16 4`` then a zlib
    stream of ``uint32 flags`` (0x1000 float32 / 0x2000 float64, 0x0001 vertex normals, 0x0002 UVs),
    the mesh name (UTF-8, NUL-terminated), ``uint64`` vertex and triangle counts, positions (normals,
    UVs), uint32 indices; the file ends with each mesh's ``uint64`` offset and the ``uint32`` mesh count."""
    out, offsets = bytearray(), []
    for name, pos, faces, nrm, uv, real in meshes:
        offsets.append(len(out))
        flags = (0x2000 if real == "<f8" else 0x1000) | (0x1 if nrm is not None else 0) | (0x2 if uv is not None else 0)
        body = struct.pack("<I", flags) + name.encode() + b"\0" + struct.pack("<QQ", len(pos), len(faces))
        for a in (pos, nrm, uv):
            body += np.asarray(a, real).tobytes() if a is not None else b""
        out += struct.pack("<HH", 0x041C, 4) + zlib.compress(body + np.asarray(faces, "<u4").tobytes())
    path.write_bytes(bytes(out) + struct.pack(f"<{len(offsets)}QI", *offsets, len(offsets)))


def test_include_and_path_resolve_like_mitsuba(tmp_path):
    (tmp_path / "parts" / "deeper").mkdir(parents=True)
    (tmp_path / "meshes").mkdir()
    (tmp_path / "parts" / "tri.ply").write_text(QUAD_PLY)  # beside the included file that names it
    (tmp_path / "meshes" / "far.ply").write_text(QUAD_PLY)  # found through <path>
    (tmp_path / "main.xml").write_text("""<scene version="3.0.0"><path value="meshes"/>
      <default name="r" value="0.25"/>
      <include filename="parts/objects.xml"/>
      <shape type="ply" id="far"><string name="filename" value="far.ply"/></shape></scene>""")
    (tmp_path / "parts" / "objects.xml").write_text("""<scene version="3.0.0">
      <shape type="ply" id="near"><string name="filename" value="tri.ply"/></shape>
      <include filename="deeper/lights.xml"/></scene>""")
    (tmp_path / "parts" / "deeper" / "lights.xml").write_text(f"""<scene version="3.0.0">{LIGHT}
      <shape type="sphere" id="ball"><float name="radius" value="$r"/></shape></scene>""")
    doc, warns = import_scene(tmp_path / "main.xml", tmp_path / "out")
    assert [s["name"] for s in doc["shapes"]] == ["near", "ball", "far"]  # in document order
    assert doc["shapes"][1]["radius"] == 0.25 and doc["lights"][0]["name"] == "bulb"
    assert not any("include" in w or "path" in w for w in warns), warns
    scene_from_dict(doc, source="imported", base=tmp_path / "out")
    # a cycle is one line naming the chain
    (tmp_path / "a.xml").write_text('<scene version="3.0.0"><include filename="b.xml"/></scene>')
    (tmp_path / "b.xml").write_text('<scene version="3.0.0"><include filename="a.xml"/></scene>')
    with pytest.raises(SceneError, match=r"cycle: a.xml -> b.xml -> a.xml"):
        import_scene(tmp_path / "a.xml", tmp_path / "o2")
    (tmp_path / "c.xml").write_text('<scene version="3.0.0"><include filename="nowhere.xml"/></scene>')
    with pytest.raises(SceneError, match="nowhere.xml.*no such file"):
        import_scene(tmp_path / "c.xml", tmp_path / "o3")


def test_serialized_meshes_become_ply(tmp_path):
    import trimesh

    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    quad = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    write_serialized(tmp_path / "m.serialized", [("a", tri, [[0, 1, 2]], None, None, "<f4"),
                                                 ("b", quad, [[0, 1, 2], [0, 2, 3]], np.tile([0, 0, 1.0], (4, 1)), uv,
                                                  "<f8")])
    (tmp_path / "s.xml").write_text(f"""<scene version="3.0.0">{LIGHT}
      <shape type="serialized" id="second"><string name="filename" value="m.serialized"/>
        <integer name="shape_index" value="1"/><transform name="to_world"><translate x="5"/></transform></shape>
      <shape type="serialized" id="first"><string name="filename" value="m.serialized"/></shape></scene>""")
    doc, _ = import_scene(tmp_path / "s.xml", tmp_path / "out")
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    assert shapes["second"].type == "ply" and shapes["second"].transform.to_matrix()[0, 3] == 5
    second = trimesh.load(tmp_path / "out" / shapes["second"].filename, process=False)
    assert np.allclose(second.vertices, quad) and second.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert np.allclose(second.vertex_normals, [0, 0, 1])
    first = trimesh.load(tmp_path / "out" / shapes["first"].filename, process=False)
    assert np.allclose(first.vertices, tri) and len(first.faces) == 1
    (tmp_path / "bad.xml").write_text(f"""<scene version="3.0.0">{LIGHT}<shape type="serialized">
      <string name="filename" value="m.serialized"/><integer name="shape_index" value="7"/></shape></scene>""")
    with pytest.raises(SceneError, match="mesh 7.*holds 2") as e:
        import_scene(tmp_path / "bad.xml", tmp_path / "o2")
    assert "\n" not in str(e.value)
    # Mitsuba itself reads the same file to the same mesh (the reader's cross-check)
    mi = pytest.importorskip("mitsuba")
    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    mesh = mi.load_dict({"type": "serialized", "filename": str(tmp_path / "m.serialized"), "shape_index": 1})
    assert np.allclose(np.array(mesh.vertex_positions_buffer()).reshape(-1, 3), second.vertices)
    assert np.array(mesh.faces_buffer()).reshape(-1, 3).tolist() == second.faces.tolist()
    assert np.allclose(np.array(mesh.vertex_texcoords_buffer()).reshape(-1, 2), uv)


LEGACY = """<?xml version="1.0" encoding="utf-8"?>
<scene version="0.5.0">
  <integrator type="path"><integer name="maxDepth" value="5"/></integrator>
  <sensor type="perspective"><float name="fov" value="40"/><string name="fovAxis" value="x"/>
    <transform name="toWorld"><lookAt origin="0, 1, 6" target="0, 1, 0" up="0, 1, 0"/></transform></sensor>
  <bsdf type="diffuse" id="red"><srgb name="reflectance" value="#bf4040"/></bsdf>
  <shape type="cube" id="box"><transform name="toWorld"><scale value="0.5"/><rotate y="1" angle="30"/>
    <translate x="1"/></transform><ref id="red"/></shape>
  <shape type="sphere"><point name="center" x="0" y="0.5" z="0"/><float name="radius" value="0.5"/>
    <bsdf type="roughplastic"><float name="intIOR" value="1.7"/><srgb name="diffuseReflectance" value="0.5, 0.5, 0.5"/></bsdf></shape>
  <shape type="disk" id="floor"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">
    <string name="filename" value="checker.png"/><float name="uscale" value="4"/></texture></bsdf></shape>
  <shape type="rectangle" id="cbox_light"><transform name="toWorld"><translate y="2.9"/></transform>
    <emitter type="area"><spectrum name="radiance" value="400:0, 500:8, 600:15.6, 700:18.4"/></emitter></shape>
  <shape type="rectangle" id="lamp"><transform name="toWorld"><rotate x="1" angle="90"/><translate y="3"/></transform>
    <emitter type="area"><blackbody name="radiance" temperature="2700K"/></emitter></shape>
</scene>"""


def test_legacy_mitsuba_05_is_upgraded_with_one_warning_per_kind(tmp_path):
    import import_testutil as t

    t.texture_png(tmp_path / "checker.png", 8)
    (tmp_path / "old.xml").write_text(LEGACY)
    doc, warns = import_scene(tmp_path / "old.xml", tmp_path / "out")
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    want = np.eye(4)
    want[0, 3] = 1
    want = want @ rotation_matrix((0, 1, 0), 30) @ np.diag([0.5, 0.5, 0.5, 1])
    assert np.allclose(shapes["box"].transform.to_matrix(), want)  # toWorld kept
    v = scene.views[0]
    assert np.allclose(v.origin, [0, 1, 6]) and np.allclose(v.target, [0, 1, 5]) and scene.max_depth == 5
    red = np.array([0xbf, 0x40, 0x40]) / 255  # sRGB-encoded → linear, decoded here by the formula
    lin = np.where(red <= 0.04045, red / 12.92, ((red + 0.055) / 1.055) ** 2.4)
    import colour

    xyz = colour.sd_to_XYZ(colour.SpectralDistribution(dict(zip(scene.materials["red"].reflectance.wavelengths,
                                                                   scene.materials["red"].reflectance.values))),
                           illuminant=colour.SDS_ILLUMINANTS["D65"]) / 100
    assert np.allclose(colour.XYZ_to_RGB(xyz, "sRGB"), lin, atol=0.02)
    plastic = next(m for k, m in scene.materials.items() if k != "red")
    assert plastic.int_ior == 1.7 and plastic.reflectance.value == pytest.approx(0.214, abs=1e-3)
    assert scene.group(shapes["lamp"].emitter.group).emission == "blackbody:2700"
    floor = scene.materials[shapes["floor"].material].reflectance
    assert floor.file.endswith("checker.png") and list(floor.scale) == [4, 1]  # uscale → to_uv
    # Mitsuba 0.5's Cornell box light (a spectrum, which once became blackbody:3120 without a word) is kept
    cbox = scene.group(shapes["cbox_light"].emitter.group).emission
    assert list(cbox.wavelengths)[2:6] == [400, 500, 600, 700] and not any("'cbox_light'" in w for w in warns)
    legacy = [w for w in warns if "legacy Mitsuba 0.5.0" in w]
    assert len(legacy) == 5, legacy  # camelCase names, <lookAt>, sRGB colours, <blackbody>, uscale: one line each
    assert any("toWorld → to_world" in w for w in legacy)
    for version, msg in (("0.3.0", "cannot be upgraded"), ("4.0.0", "newer"), ("three", "not a version")):
        (tmp_path / "v.xml").write_text(LEGACY.replace('version="0.5.0"', f'version="{version}"'))
        with pytest.raises(SceneError, match=msg) as e:
            import_scene(tmp_path / "v.xml", tmp_path / "o2")
        assert "\n" not in str(e.value)


def test_nothing_renderable_exits_2_for_every_importer(tmp_path, capsys):
    import import_testutil as t

    (tmp_path / "noshape.xml").write_text(f'<scene version="3.0.0">{LIGHT}<shape type="hair"/></scene>')
    (tmp_path / "dark.xml").write_text('<scene version="3.0.0"><shape type="sphere"/></scene>')
    (tmp_path / "dark.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    pygltflib = pytest.importorskip("pygltflib")
    g = pygltflib.GLTF2().load(str(t.write_gltf(tmp_path / "g.gltf")))
    for n in g.nodes:  # lights and a camera, no mesh (glTF adds a sky itself when it has no lights)
        n.mesh = None
    g.save(str(tmp_path / "empty.gltf"))
    for name, why in (("noshape.xml", "no shape"), ("dark.xml", "nothing emits light"),
                      ("dark.obj", "nothing emits light"), ("empty.gltf", "no shape")):
        code, out, err = run_cli(capsys, "import", str(tmp_path / name), "--out", str(tmp_path / "x.yaml"))
        assert code == 2, (name, code, err)
        line = assert_one_line_error(code, out, err)
        assert name in line and why in line, line
    assert not (tmp_path / "x.yaml").exists()
    code, out, err = run_cli(capsys, "import", str(tmp_path / "dark.obj"), "--out", str(tmp_path / "x.yaml"), "--sky")
    assert code == 0 and "constant sky" in err
