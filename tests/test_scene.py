"""Scene description (scene.schema, scene_model, scene_load) and procedural scenes (scene.demo): no rendering."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from illumix.scene import demo
from illumix.scene.load import dump_scene, load_scenes, scene_from_dict
from illumix.scene.schema import SceneError, Transform, rotation_matrix

BASE = {
    "name": "t1",
    "materials": {
        "grey": {"kind": "diffuse", "reflectance": {"value": 0.5}},
        "cc": {"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "index": 3}},
        "plastic": {"kind": "roughplastic", "reflectance": {"wavelengths": [380, 780], "values": [0.2, 0.6]}},
        "metal": {"kind": "roughconductor", "conductor": "Au", "alpha": 0.3},
        "glass": {"kind": "dielectric"},
    },
    "shapes": [
        {"name": "floor", "type": "rectangle", "material": "grey"},
        {"name": "ball", "type": "sphere", "material": "cc", "radius": 0.5, "center": [0, 0.5, 0]},
        {"name": "lamp", "type": "disk", "emitter": {"group": "lamp", "strength": 3},
         "transform": {"translate": [0, 2, 0], "rotate": [{"axis": [1, 0, 0], "angle": 90}]}},
    ],
    "lights": [{"name": "sun", "type": "directional", "group": "day", "direction": [0, -1, 0], "strength": 1}],
    "views": [{"name": "v0", "origin": [0, 1, 3], "target": [0, 0, 0]}],
}


def doc(**changes):
    d = json.loads(json.dumps(BASE))
    for path, value in changes.items():
        node = d
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[int(k)] if k.isdigit() else node[k]
        last = keys[-1]
        if last.isdigit():
            node[int(last)] = value
        else:
            node[last] = value
    return d


def err(d, tmp_path=None) -> str:
    with pytest.raises(SceneError) as ei:
        scene_from_dict(d, source="s.yaml", base=tmp_path)
    msg = str(ei.value)
    assert "\n" not in msg
    return msg


def test_valid_scene_groups_emission_and_hash():
    s = scene_from_dict(BASE)
    assert s.group_names == ["lamp", "day"]
    assert np.all(s.emission("lamp") == 1.0) and len(s.emission("lamp")) == 63
    assert len(s.scene_hash) == 64 and s.scene_hash == scene_from_dict(BASE).scene_hash
    assert [e.name for e in s.emitters_of("lamp")] == ["lamp"]
    # reflectance of ColorChecker patch 4 (foliage) is the library's band averages
    from illumix.retarget.reflectances import get_reflectances

    _, r = get_reflectances("ColorChecker N Ohta")
    np.testing.assert_array_equal(s.spectrum(s.materials["cc"].reflectance, "x"), r[3])


def test_errors_name_object_and_field():
    assert "shapes[1] (ball).radius" in err(doc(shapes__1__radius=-1))
    m = err(doc(shapes__0__material="nope"))
    assert "shapes[0] (floor): material: unknown material 'nope'" in m
    assert "lights[0] (sun).direction" in err(doc(lights__0__direction=[0, 0, 0]))
    assert "views" in err(doc(views=[]))
    assert "name 'floor'" in err(doc(shapes__1__name="floor"))
    m = err(doc(materials__cc={"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "index": 30}}))
    assert "materials.cc.reflectance" in m and "index 30 out of range" in m
    assert "exceeds 1" in err(doc(materials__grey={"kind": "diffuse", "reflectance": {"value": 1.5}}))
    assert "unknown conductor 'Unobtainium'" in err(doc(materials__metal={"kind": "roughconductor",
                                                                         "conductor": "Unobtainium"}))
    # declared light groups must cover every emitter
    m = err(doc(light_groups=[{"name": "lamp"}]))
    assert "lights[0] (sun): group: unknown light group 'day'" in m
    assert "no emitters" in err(doc(shapes=[BASE["shapes"][0]], lights=[]))
    assert "beam_width" in err(doc(lights=[{"name": "s", "type": "spot", "group": "g", "position": [0, 1, 0],
                                            "target": [0, 0, 0], "cutoff_angle": 10, "beam_width": 20,
                                            "strength": 1}]))
    assert "shapes[0] (floor).type" in err(doc(shapes__0__type="torus"))
    assert "'..'" in err(doc(name="a..b"))
    m = err(doc(shapes__2__emitter={"group": "lamp", "strength": 1, "portal": True}, shapes__2__material="grey"))
    assert "shapes[2] (lamp): material: a portal is not geometry" in m
    # Mitsuba keeps spheres round under any transform: a non-uniform scale would render another shape
    assert "shapes[1] (ball): a sphere's transform must scale uniformly" in err(
        doc(shapes__1__transform={"scale": [3, 0.3, 1]}))
    scene_from_dict(doc(shapes__1__transform={"scale": 2, "rotate": [{"axis": [1, 0, 0], "angle": 30}]}))


def test_missing_files_and_zero_emission(tmp_path):
    m = err(doc(shapes=BASE["shapes"] + [{"name": "mesh", "type": "obj", "filename": "no.obj", "material": "grey"}]),
            tmp_path)
    assert "no.obj" in m and "does not exist" in m
    m = err(doc(materials__grey={"kind": "diffuse", "reflectance": {"file": "refl.csv"}}), tmp_path)
    assert "refl.csv" in m
    d = doc(light_groups=[{"name": "lamp"}, {"name": "day", "emission": {"wavelengths": [300, 900],
                                                                        "values": [0, 0]}}])
    assert "light_groups (day): emission" in err(d, tmp_path)


def test_csv_reflectance_relative_path_and_hash_tracks_file(tmp_path):
    csv = tmp_path / "refl.csv"
    csv.write_text("wavelength,r\n380,0.1\n780,0.9\n")
    d = doc(materials__grey={"kind": "diffuse", "reflectance": {"file": "refl.csv"}})
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(d))
    s = load_scenes(tmp_path / "scene.yaml")[0]
    r = s.spectrum(s.materials["grey"].reflectance, "grey")
    assert r[0] < r[-1] and 0.1 <= r.min() and r.max() <= 0.9
    h1 = s.scene_hash
    csv.write_text("wavelength,r\n380,0.2\n780,0.9\n")
    assert load_scenes(tmp_path / "scene.yaml")[0].scene_hash != h1


def test_hash_ignores_views_but_not_materials():
    h = scene_from_dict(BASE).scene_hash
    assert scene_from_dict(doc(views__0__fov=30)).scene_hash == h
    assert scene_from_dict(doc(materials__grey={"kind": "diffuse", "reflectance": {"value": 0.4}})).scene_hash != h
    s1, s2 = scene_from_dict(BASE), scene_from_dict(doc(views__0__fov=30))
    assert s1.view_hash("v0") != s2.view_hash("v0")


def test_yaml_json_roundtrip_and_multi_scene_files(tmp_path):
    s = scene_from_dict(BASE)
    for ext in ("yaml", "json"):
        dump_scene(s, tmp_path / f"s.{ext}")
        assert load_scenes(tmp_path / f"s.{ext}")[0].scene_hash == s.scene_hash
    other = doc(name="t2")
    (tmp_path / "multi.yaml").write_text(yaml.safe_dump({"scenes": [BASE, other]}))
    assert [x.name for x in load_scenes(tmp_path / "multi.yaml")] == ["t1", "t2"]
    (tmp_path / "dup.yaml").write_text(yaml.safe_dump({"scenes": [BASE, BASE]}))
    with pytest.raises(SceneError, match="duplicate scene names"):
        load_scenes(tmp_path / "dup.yaml")
    (tmp_path / "bad.yaml").write_text("name: [unclosed\n")
    with pytest.raises(SceneError, match="not valid YAML"):
        load_scenes(tmp_path / "bad.yaml")
    with pytest.raises(SceneError, match="does not exist"):
        load_scenes(tmp_path / "missing.yaml")


def test_transform_order_scale_rotate_translate():
    t = Transform(scale=2.0, rotate=[{"axis": (0, 0, 1), "angle": 90}], translate=(1, 0, 0))
    p = t.to_matrix() @ np.array([1.0, 0, 0, 1])
    np.testing.assert_allclose(p[:3], [1, 2, 0], atol=1e-12)  # scale → (2,0,0), rotate → (0,2,0), +x
    r = rotation_matrix((1, 0, 0), 90)
    np.testing.assert_allclose(r[:3, :3] @ [0, 0, 1], [0, -1, 0], atol=1e-12)
    with pytest.raises(ValueError):
        Transform(matrix=[[1, 0, 0, 0]] * 4)
    with pytest.raises(ValueError):
        Transform(matrix=np.eye(4).tolist(), scale=2)


def test_library_emission_is_normalised_illuminant():
    from illumix.retarget.illuminants import illuminant_spd

    s = scene_from_dict(doc(light_groups=[{"name": "lamp", "emission": "FL11"}, {"name": "day"}]))
    np.testing.assert_allclose(s.emission("lamp"), illuminant_spd("FL11"))
    assert s.emission_name("lamp") == "FL11" and s.emission_name("day") == "flat"


def test_demo_room_is_seeded_and_complete():
    a, b, c = demo.demo_room_dict(3), demo.demo_room_dict(3), demo.demo_room_dict(4)
    assert json.dumps(a, sort_keys=True, default=list) == json.dumps(b, sort_keys=True, default=list)
    assert json.dumps(a, sort_keys=True, default=list) != json.dumps(c, sort_keys=True, default=list)
    s = demo.demo_room(3, resolution=(64, 48))
    assert len(s.views) >= 2 and all(v.resolution == (64, 48) for v in s.views)
    assert s.group_names == ["daylight", "ceiling", "desk"]
    day = s.emitters_of("daylight")
    assert {e.type for e in day} == {"directional", "rectangle"}
    assert [e.name for e in day if s.is_portal(e)] == ["window_sky"]
    patches = [x for x in s.shapes if x.name.startswith("cc_") and x.name != "cc_board"]
    assert len(patches) == 24
    kinds = {m.kind for m in s.materials.values()}
    assert {"diffuse", "roughplastic", "roughconductor", "dielectric"} <= kinds
    assert {x.type for x in s.shapes} >= {"rectangle", "cube", "sphere", "cylinder", "disk"}


def test_chart_patch_layout_in_chart_order():
    c = demo.chart_patch_centers((0, 0, 0), (0, 0, 1), (0, 1, 0), 0.1, 0.02)
    assert len(c) == 24
    assert c[0][0] < c[5][0] and c[0][1] > c[18][1]      # 1 top-left, 6 top-right, 19 bottom-left
    assert math.isclose(c[1][0] - c[0][0], 0.12) and math.isclose(c[0][1] - c[6][1], 0.12)


def test_example_scene_loads():
    from pathlib import Path

    from illumix import renderer_jobs

    (s,) = load_scenes(Path(renderer_jobs.__file__).parent / "examples" / "two_lamps.yaml")
    assert s.group_names == ["ceiling", "lamp", "ambient"] and len(s.views) == 2
