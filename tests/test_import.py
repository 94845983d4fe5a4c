"""Scene importers (glTF, OBJ + MTL, Mitsuba XML): each round-trips a small file the test writes itself
into a document the schema accepts and Mitsuba loads, with the right transforms, camera poses and
light-group illuminants; unsupported features are warnings naming the object; the rule file assigns
groups; ``illumix import`` works and refuses bad input with one line; and a textured glTF renders its
texture's colours (ΔE00 against the Jakob–Hanika spectra's own colours)."""

from __future__ import annotations

import math

import colour
import numpy as np
import pytest

import import_testutil as t
from cli_testutil import run_cli
from illumix.scene.load import load_scenes, scene_from_dict
from illumix.scene.schema import SceneError, rotation_matrix
from illumix.scene_import import import_scene
from illumix.scene_import.colour_match import illuminant_for, illuminant_xy, rgb_light
from illumix.scene_import.rules import load_rules, rules_from_dict

EACH = rules_from_dict({"grouping": "each"})  # one group per light (the default groups by kind and CCT)
from test_cli_spectra import assert_one_line_error


def _load(doc, base):
    return scene_from_dict(doc, source="imported", base=base)


def _mitsuba_loads(scene, view):
    pytest.importorskip("mitsuba")
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene

    ms, sensor = load_mitsuba_scene(scene, view, None)
    assert len(ms.shapes()) >= 1 and sensor is not None


def _has(warnings, *words):
    return any(all(w in msg for w in words) for msg in warnings)


@pytest.mark.parametrize("glb", [False, True], ids=["gltf", "glb"])
def test_gltf_round_trip(tmp_path, glb):
    doc, warns = import_scene(t.write_gltf(tmp_path / ("s.glb" if glb else "s.gltf"), glb=glb), tmp_path / "out", EACH)
    scene = _load(doc, tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    # GlowPanel: translate (0, 3, -2) · rotate 90° about x · scale 0.5 (glTF's T·R·S)
    want = np.eye(4)
    want[:3, 3] = [0, 3, -2]
    want = want @ rotation_matrix((1, 0, 0), 90) @ np.diag([0.5, 0.5, 0.5, 1])
    assert np.allclose(shapes["GlowPanel"].transform.to_matrix(), want, atol=1e-9)
    assert np.allclose(shapes["Canvas"].transform.to_matrix(), np.eye(4))
    assert scene.materials["Painted"].kind == "diffuse" and scene.materials["Painted"].reflectance.file.endswith(".png")
    assert scene.materials["Glow"].kind == "roughplastic" and math.isclose(scene.materials["Glow"].alpha, 0.25)
    # camera at z = 4 looking down −z, +y up; yfov 2·atan(1/4) at aspect 1 is the same horizontally
    v = scene.view("Front")
    assert np.allclose(v.origin, [0, 0, 4]) and np.allclose(np.subtract(v.target, v.origin), [0, 0, -1])
    assert np.allclose(v.up, [0, 1, 0]) and math.isclose(v.fov, math.degrees(2 * math.atan(0.25)), rel_tol=1e-6)
    assert v.resolution == (320, 320)
    lights = {li.name: li for li in scene.lights}
    assert np.allclose(lights["Sun"].direction, [0, 0, -1])
    assert np.allclose(lights["Lamp_warm"].position, [1, 2, 3])
    # the spot hangs under "Rig" (y + 1), rotated −90° about x: it points straight down from (0, 3, 0)
    spot = lights["Spot"]
    assert np.allclose(spot.position, [0, 3, 0]) and np.allclose(np.subtract(spot.target, spot.position), [0, -1, 0])
    assert math.isclose(spot.cutoff_angle, math.degrees(0.5)) and math.isclose(spot.beam_width, math.degrees(0.2))
    # colours → illuminants: white → D65; (1, 0.6, 0.3) → a ~3670 K blackbody; strength = intensity × Y
    assert scene.group("Sun").emission == "D65" and scene.group("Spot").emission == "D65"
    warm = scene.group("Lamp_warm").emission  # CCT by Ohno 2013, checked against Hernandez 1999 (±20 K here)
    hernandez = colour.xy_to_CCT(colour.XYZ_to_xy(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ @ [1, 0.6, 0.3]),
                                 method="Hernandez 1999")
    assert warm.startswith("blackbody:") and abs(float(warm.split(":")[1]) - hernandez) <= 20
    assert math.isclose(lights["Lamp_warm"].strength, 20 * rgb_light([1, 0.6, 0.3])[1], rel_tol=1e-6)
    assert shapes["GlowPanel"].emitter.group == "Glow"
    # unsupported features are warnings naming the object
    assert _has(warns, "material 'Glow'", "KHR_materials_clearcoat")
    assert _has(warns, "material 'Glow'", "normal map")
    assert _has(warns, "light 'Lamp warm'", "range")
    assert _has(warns, "GlowPanel", "blackbody")  # a red glow is not a CIE illuminant: said, not silent
    _mitsuba_loads(scene, "Front")


def test_cct_picks_the_illuminant():
    assert illuminant_for(rgb_light([1, 1, 1])[0])[0] == "D65"
    assert illuminant_for(illuminant_xy("A"))[0] == "A"
    assert illuminant_for(illuminant_xy("D50"))[0] == "D50"
    # parametric ones come back within the 10 K rounding (xy taken from the 395–705 nm band averages)
    name, cct = illuminant_for(illuminant_xy("daylight:9000"))
    assert name.startswith("daylight:") and abs(float(name.split(":")[1]) - 9000) <= 20
    name, cct = illuminant_for(illuminant_xy("blackbody:2200"))
    assert name.startswith("blackbody:") and abs(float(name.split(":")[1]) - 2200) <= 20 and abs(cct - 2200) < 20


def test_obj_round_trip(tmp_path):
    doc, warns = import_scene(t.write_obj(tmp_path / "room.obj"), tmp_path / "out", EACH)
    scene = _load(doc, tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    assert set(shapes) == {"room-floor", "room-red", "panel"}
    assert scene.materials["floor"].reflectance.file.endswith(".png")
    red = scene.materials["red"]
    assert red.kind == "roughplastic" and math.isclose(red.alpha, math.sqrt(2 / 102))
    assert shapes["panel"].emitter.group == "lamp" and math.isclose(shapes["panel"].emitter.strength, 4, rel_tol=1e-6)
    assert scene.group("lamp").emission == "D65"
    assert shapes["panel"].face_normals and not shapes["room-floor"].face_normals
    assert _has(warns, "material 'floor'", "bump") and _has(warns, "no cameras", "default")
    import trimesh

    floor = trimesh.load(tmp_path / "out" / shapes["room-floor"].filename, process=False)
    assert np.allclose(floor.bounds, [[-2, 0, -2], [2, 0, 2]])
    v = scene.view("default")
    lo, hi = np.array([-2, 0, -2]), np.array([2, 2.5, 2])
    look = np.subtract(v.target, v.origin)
    to_centre = (lo + hi) / 2 - np.asarray(v.origin)
    assert np.allclose(look / np.linalg.norm(look), to_centre / np.linalg.norm(to_centre), atol=1e-6)  # at the centre
    _mitsuba_loads(scene, "default")


def test_mitsuba_xml_round_trip(tmp_path):
    doc, warns = import_scene(t.write_xml(tmp_path / "s.xml"), tmp_path / "out", EACH)
    scene = _load(doc, tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    # scale 3, then rotate −90° about x, then translate y −0.01 (Mitsuba applies them in that order)
    want = np.eye(4)
    want[1, 3] = -0.01
    want = want @ rotation_matrix((1, 0, 0), -90) @ np.diag([3, 3, 3, 1])
    assert np.allclose(shapes["floor"].transform.to_matrix(), want, atol=1e-9)
    assert scene.materials["floor-mat"].two_sided and not scene.materials["textured"].two_sided
    assert scene.materials["textured"].reflectance.file.endswith("checker.png")
    assert shapes["ball"].center == (0.5, 0.5, 0.0) and scene.materials["ball-bsdf"].alpha == 0.2
    v = scene.view("cam")  # lookat 0,2,5 → 0,0.5,0; fov 45 along x; film $res × 48
    d = np.subtract(v.target, v.origin)
    assert np.allclose(v.origin, [0, 2, 5]) and np.allclose(d / np.linalg.norm(d), np.array([0, -1.5, -5]) / math.hypot(1.5, 5))
    assert v.fov == 45 and v.resolution == (64, 48) and scene.max_depth == 6
    assert np.dot(v.up, d) == pytest.approx(0, abs=1e-9) and v.up[1] > 0.9
    assert scene.group("Lamp1").emission.startswith("blackbody:3")
    assert scene.group("ceiling_panel").emission == "D65"
    assert _has(warns, "velvet-ball", "hair") and _has(warns, "emitter 'sky'", "sunsky")
    rail = scene.materials[shapes["rail"].material]
    assert rail.kind == "roughconductor" and rail.conductor == "Au" and _has(warns, "rail", "smooth conductor")
    assert shapes["rail"].p1 == (-1.0, 2.0, -1.0)
    _mitsuba_loads(scene, "cam")


def test_rules_assign_groups(tmp_path):
    rules = tmp_path / "rules.yaml"
    rules.write_text("groups:\n  - {name: ceiling, match: ['CEILING_*'], illuminant: F11}\n"
                     "  - {name: lamps, match: ['Lamp*', 'desk*'], description: desk lamps}\n"
                     "  - {name: unused, match: ['nothing*']}\ndefault_group: other\n")
    doc, warns = import_scene(t.write_xml(tmp_path / "s.xml"), tmp_path / "out", rules)
    scene = _load(doc, tmp_path / "out")
    assert scene.group_names == ["ceiling", "lamps"]
    assert scene.group("ceiling").emission == "FL11"  # F11 is colour-science's FL11
    assert scene.group("lamps").description == "desk lamps"
    assert _has(warns, "'unused'", "matches no light")
    gdoc, _ = import_scene(t.write_gltf(tmp_path / "g.gltf"), tmp_path / "o2", rules)
    assert {g["name"] for g in gdoc["light_groups"]} == {"lamps", "other"}  # Sun, Spot, Glow: no rule names them
    for bad, msg in (("groups: [{name: x}]", "match"), ("groups: [{name: x, match: [a], illuminant: D56}]", "D56"),
                     ("groups: [{name: 'a b', match: [a]}]", "pattern"), ("colour: 3", "colour"), ("[1, 2]", "mapping")):
        rules.write_text(bad)
        with pytest.raises(SceneError, match=msg) as e:
            load_rules(rules)
        assert "\n" not in str(e.value)


def test_cli_import_and_render_dry_run(tmp_path, capsys):
    src = t.write_xml(tmp_path / "s.xml")
    code, out, err = run_cli(capsys, "import", str(src), "--out", str(tmp_path / "o" / "scene.yaml"))
    assert code == 0, err
    assert out.startswith("imported s.xml") and "6 shapes" in out and "2 light groups" in out
    assert "illumix: warning: bsdf 'velvet-ball-bsdf'" in err
    scene = load_scenes(tmp_path / "o" / "scene.yaml")[0]
    assert (tmp_path / "o" / "scene_assets" / "checker.png").is_file() and len(scene.shapes) == 6
    assert not [p for p in (tmp_path / "o").iterdir() if p.name.startswith(".")]  # no temporary left over
    # `illumix render` takes the imported formats directly (a dry run renders nothing)
    rules = tmp_path / "r.yaml"
    rules.write_text("groups: [{name: all, match: ['*']}]\n")
    code, out, err = run_cli(capsys, "render", str(src), "--store", str(tmp_path / "st"), "--rules", str(rules),
                             "--dry-run", "--json")
    assert code == 0, err
    assert '"cubes_to_render": 1' in out and "s/cam/all" in err.replace("\n", "")
    for argv, msg in ((["import", str(tmp_path / "x.fbx"), "--out", str(tmp_path / "a.yaml")], ".gltf, .glb, .obj, .xml"),
                      (["import", str(tmp_path / "missing.obj"), "--out", str(tmp_path / "a.yaml")], "does not exist"),
                      (["import", str(src), "--out", str(tmp_path / "a.txt")], ".yaml"),
                      (["import", str(src), "--out", str(tmp_path / "a.yaml"), "--rules", str(src)], "rule"),
                      (["render", str(tmp_path / "x.fbx"), "--store", str(tmp_path / "st")], ".gltf"),
                      (["import", str(tmp_path / "x.blend"), "--out", str(tmp_path / "a.yaml")], "illumix render")):
        (tmp_path / "x.blend").write_bytes(b"BLENDER")
        if argv[1].endswith(".fbx"):
            (tmp_path / "x.fbx").write_text("not a scene")
        line = assert_one_line_error(*run_cli(capsys, *argv))
        assert msg in line, line
    assert not (tmp_path / "a.yaml").exists()


def test_import_help_is_cheap():
    from test_cli_startup import run_fresh

    code, printed, heavy = run_fresh("import", "--help")
    assert code == 0 and "--rules" in printed and heavy == []


def test_load_scene_file_caches_the_import(tmp_path):
    from illumix.scene_files import import_cached, load_scene_file

    src = t.write_obj(tmp_path / "room.obj")
    with pytest.warns(UserWarning) as caught:
        scenes = load_scene_file(src)
    assert _has([str(w.message) for w in caught], "room.obj", "no cameras")
    assert scenes[0].name == "room" and scenes[0].generator["format"] == "obj"
    first, _ = import_cached(src)
    stamp = first.stat().st_mtime_ns
    again, warns = import_cached(src)
    assert again == first and again.stat().st_mtime_ns == stamp and _has(warns, "no cameras")


def test_an_edited_mtl_beside_the_obj_is_imported_again(tmp_path):
    """The cache key covers the files beside the scene file (an MTL, an included XML, a texture),
    not the main file alone: an edited material is not served from a stale import."""
    import os

    from illumix.scene_files import import_cached

    src = t.write_obj(tmp_path / "room.obj")
    first, _ = import_cached(src)
    mtl = next(tmp_path.glob("*.mtl"))
    mtl.write_text(mtl.read_text() + "\n# edited\n")
    os.utime(mtl, ns=(mtl.stat().st_atime_ns, mtl.stat().st_mtime_ns + 10**9))
    again, _ = import_cached(src)
    assert again != first and again.is_file()


# The required check: Mitsuba lifts the texture's sRGB texels by Jakob–Hanika; the rendered colour of
# each patch under D65 must be the colour of colour-science's Jakob–Hanika spectrum of that texel.
# Tolerance ΔE00 0.5: the quad is lit directly by a distant light along its normal, so a pixel's only
# randomness is where its 16 samples land and which wavelengths they carry — the 10×10-pixel patch
# means come out within ~0.1 % (measured ΔE00 0.03–0.06); the rest of the budget covers the two
# Jakob–Hanika implementations (Mitsuba's precomputed coefficient table vs colour-science's fit).
DELTA_E00_TOLERANCE = 0.5


def test_textured_gltf_renders_the_texture_colours(tmp_path):
    pytest.importorskip("mitsuba")
    import colour

    from illumix.scene_import.colour_match import jakob_hanika as _upsample
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.retarget.grid import resample
    from illumix.scene_import.colour_match import srgb_decode

    doc, _ = import_scene(t.write_gltf(tmp_path / "s.gltf"), tmp_path / "out", EACH)
    doc["views"][0]["resolution"] = [32, 32]
    scene = _load(doc, tmp_path / "out")
    assert scene.group("Sun").emission == "D65"
    cube = render_cube(scene, "Front", "Sun", RenderSettings(spp=16)).cube
    grid = scene.spectral_grid
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    bars = np.stack([resample(cmfs.wavelengths, cmfs.values[:, i], grid) for i in range(3)], axis=1)
    e = scene.emission("Sun") * 3.0  # the sun's irradiance: strength 3 × D65 (photometrically normalised)
    white = e @ bars  # a white Lambertian facing the sun, × π
    white_xy = colour.XYZ_to_xy(white / white[1])
    # the camera frames [-1, 1]² exactly: patch centres at pixels 8 and 24; average 10×10 inside each
    for (r, c), (py, px) in zip([(0, 0), (0, 1), (1, 0), (1, 1)], [(8, 8), (8, 24), (24, 8), (24, 24)], strict=True):
        patch = cube[py - 5:py + 5, px - 5:px + 5].reshape(-1, cube.shape[2]).mean(axis=0) * math.pi
        xyz = patch @ bars / white[1]
        lin = srgb_decode(t.PATCHES[r, c] / 255.0)
        values, _ = _upsample(tuple(round(float(x), 6) for x in lin))
        rho = resample(np.arange(380.0, 781.0, 5.0), np.asarray(values), grid)
        ref = (rho * e) @ bars / white[1]
        de = float(colour.delta_E(colour.XYZ_to_Lab(xyz, white_xy), colour.XYZ_to_Lab(ref, white_xy),
                                  method="CIE 2000"))
        assert de < DELTA_E00_TOLERANCE, (r, c, de, xyz, ref)


def test_malformed_files_fail_with_one_line(tmp_path, capsys):
    bad = {"a.gltf": '{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 3}]}',
           "b.obj": "v 0 0 0\nv 1 0 0\nf 1 2 7\n", "c.xml": "<scene><shape type='sphere'><float name='radius' "
           "value='big'/></shape></scene>", "d.xml": "<scene><shape", "e.glb": "not binary"}
    for name, text in bad.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(SceneError) as e:
            import_scene(tmp_path / name, tmp_path / "out")
        assert str(e.value).startswith(str(tmp_path / name)) and "\n" not in str(e.value), str(e.value)
        line = assert_one_line_error(*run_cli(capsys, "import", str(tmp_path / name), "--out", str(tmp_path / "x.yaml")))
        assert name in line


def test_degenerate_cameras_and_materials(tmp_path):
    """A top-down <lookat> (up parallel to the view) gets another up and a warning, not a NaN view; a
    camera whose origin is its target is one line; a negative MTL Ns counts as 0."""
    xml = """<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="45"/>
      <transform name="to_world"><lookat origin="0,1,0" target="{t}" up="0,1,0"/></transform></sensor>
      <shape type="rectangle"><bsdf type="diffuse"/></shape>
      <emitter type="point"><point name="position" x="0" y="2" z="0"/></emitter></scene>"""
    (tmp_path / "top.xml").write_text(xml.format(t="0,0,0"))
    doc, warns = import_scene(tmp_path / "top.xml", tmp_path / "o1")
    v = scene_from_dict(doc, base=tmp_path / "o1").views[0]
    assert np.all(np.isfinite([*v.origin, *v.target, *v.up])) and np.allclose(v.up, [0, 0, -1])
    assert _has(warns, "up is parallel")
    (tmp_path / "same.xml").write_text(xml.format(t="0,1,0"))
    with pytest.raises(SceneError, match="origin = target"):
        import_scene(tmp_path / "same.xml", tmp_path / "o2")
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\nNs -2\n")
    (tmp_path / "t.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n")
    doc, _ = import_scene(tmp_path / "t.obj", tmp_path / "o3", sky=True)
    assert all(np.isfinite(m.get("alpha", 1.0)) for m in doc["materials"].values())


def test_one_importer_registry_keyed_by_extension(tmp_path):
    """Issue 34: every importable extension, .blend included, is one registry (scene_import.IMPORTERS);
    the scene room's loader reads illumix's own files and points a Blender file at its importer."""
    import warnings

    from illumix.scene.load import load_scenes
    from illumix.scene_import import IMPORTERS, load_file

    assert set(IMPORTERS) == {".gltf", ".glb", ".obj", ".xml", ".blend"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (scene,) = load_file(t.write_obj(tmp_path / "room.obj"), out_dir=tmp_path / "out")
    assert scene.group_names and (tmp_path / "out" / "scene.yaml").is_file()
    (tmp_path / "x.blend").write_bytes(b"BLENDER")
    with pytest.raises(SceneError, match="Blender file: import it"):
        load_scenes(tmp_path / "x.blend")


def test_obj_finds_its_mtl_and_maps_like_exporters_write_them(tmp_path, monkeypatch):
    """Issue 39: ``mtllib`` relative to the OBJ's folder (not the working folder), a name with spaces,
    Windows separators; ``map_Kd``/``map_Ke`` relative to the MTL's folder, with options skipped."""
    models = tmp_path / "models"
    (models / "materials" / "tex").mkdir(parents=True)
    t.texture_png(models / "materials" / "tex" / "wood.png", 8)
    from PIL import Image

    Image.new("RGB", (4, 4), (255, 128, 0)).save(models / "materials" / "tex" / "glow.png")
    (models / "materials" / "my room.mtl").write_text(
        "newmtl wood\nKd 1 1 1\nmap_Kd -s 2 2 1 -bm 0.5 tex/wood.png\n\n"
        "newmtl neon\nKd 0 0 0\nKe 2 2 2\nmap_Ke tex\\glow.png\n")
    (models / "room.obj").write_text(
        "mtllib materials\\my room.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 2 0\nv 1 2 0\nv 1 2 1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nusemtl wood\nf 1/1 2/2 3/3\no sign\nusemtl neon\nf 4 5 6\n")
    monkeypatch.chdir(tmp_path)  # elsewhere: names must not resolve against the working folder
    doc, warns = import_scene(models / "room.obj", tmp_path / "out", EACH)
    scene = _load(doc, tmp_path / "out")
    assert scene.materials["wood"].reflectance.file.endswith(".png")
    assert _has(warns, "material 'wood'", "-s 2 2 1", "-bm 0.5") and not _has(warns, "grey")
    sign = next(s for s in scene.shapes if s.emitter is not None)
    glow = colour.models.eotf_sRGB(np.array([1.0, 128 / 255, 0.0])) * 2  # Ke × the map's linear colour
    assert math.isclose(sign.emitter.strength, rgb_light(glow)[1], rel_tol=1e-6)
    assert _has(warns, "material 'neon'", "map_Ke", "averaged")


def test_a_store_rendered_beside_the_scene_does_not_make_a_new_import(tmp_path):
    """Only what an importer may read counts in the cache key: a cube store (or an import cache)
    beside the scene file, rewritten by every render, must not make every load a new import."""
    from illumix.scene_files import import_cached

    src = t.write_obj(tmp_path / "room.obj")
    first, _ = import_cached(src)
    store = tmp_path / "my-store"
    (store / "room" / "c").mkdir(parents=True)
    (store / "zarr.json").write_text("{}")
    (store / "room" / "c" / "0").write_bytes(b"chunk")
    (tmp_path / "notes.txt").write_text("not read by any importer")
    again, _ = import_cached(src)
    assert again == first
