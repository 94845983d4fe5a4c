"""Issue 39: names like Blender's ``Cube.001`` (duplicates; kept by glTF exported from Blender; Mitsuba
ids; OBJ groups) become renderer-safe unique keys in every importer, the originals are recorded, the
imported scene renders; and a hand-written scene with a '.' in a shape or light name is refused up front."""

from __future__ import annotations

import numpy as np
import pytest

from illumix.scene.load import scene_from_dict
from illumix.scene.schema import SceneError
from illumix.scene_import import import_scene
from illumix.scene_import.names import Names, key_name

QUAD = "v {x0} 0 -1\nv {x1} 0 -1\nv {x1} 0 1\nv {x0} 0 1\n"


def _obj(path):
    """Three objects named like Blender's duplicates, a material ``Material.001`` and an emissive
    ``Light.001`` on a panel above them (what Blender's OBJ exporter writes for duplicated objects)."""
    path.with_suffix(".mtl").write_text("newmtl Material.001\nKd 0.5 0.5 0.5\n\nnewmtl Light.001\nKd 0 0 0\nKe 3 3 3\n")
    text = f"mtllib {path.with_suffix('.mtl').name}\n"
    for i, name in enumerate(("Cube", "Cube.001", "Cube_001")):
        text += f"o {name}\n" + QUAD.format(x0=3 * i - 4, x1=3 * i - 2) + "usemtl Material.001\n" \
                f"f {4 * i + 1} {4 * i + 2} {4 * i + 3} {4 * i + 4}\n"
    text += "o Lamp.001\nv -1 2 -1\nv -1 2 1\nv 1 2 1\nv 1 2 -1\nusemtl Light.001\nf 13 14 15 16\n"
    path.write_text(text)
    return path


def test_key_names_are_unique_and_dot_free():
    n = Names()
    keys = [n(x) for x in ("Cube", "Cube.001", "Cube_001", "Cube.001", "..hidden", "a b/c", "")]
    assert keys == ["Cube", "Cube_001", "Cube_001-2", "Cube_001-3", "hidden", "a_b_c", "unnamed"]
    assert n.renamed == {"Cube.001": "Cube_001", "Cube_001": "Cube_001-2", "..hidden": "hidden", "a b/c": "a_b_c"}
    assert key_name("x" * 300) == "x" * 100


def test_obj_with_blender_duplicates_imports_and_renders(tmp_path):
    pytest.importorskip("mitsuba")
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    doc, warns = import_scene(_obj(tmp_path / "dups.obj"), tmp_path / "out")
    names = [s["name"] for s in doc["shapes"]]
    assert names == ["Cube", "Cube_001", "Cube_001-2", "Lamp_001"]
    assert set(doc["materials"]) == {"Material_001", "Light_001"}
    assert all("." not in s["material"] for s in doc["shapes"])
    renamed = doc["generator"]["renamed"]
    assert "'Cube.001' -> Cube_001" in renamed and "'Material.001' -> Material_001" in renamed
    assert any("renderer-safe" in w for w in warns)
    doc["views"][0]["resolution"] = [24, 18]
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    (group,) = scene.group_names
    cube = render_cube(scene, scene.views[0].name, group, RenderSettings(spp=4)).cube
    assert cube.shape[:2] == (18, 24) and np.all(np.isfinite(cube)) and float(cube.max()) > 0


def test_mitsuba_and_gltf_names_are_sanitised(tmp_path):
    (tmp_path / "s.xml").write_text("""<scene version="3.0.0">
      <shape type="rectangle" id="Plane.001"><bsdf type="diffuse" id="Mat.002"/></shape>
      <shape type="rectangle" id="Plane.001"><bsdf type="diffuse"/></shape>
      <emitter type="point" id="Point.003"><point name="position" x="0" y="1" z="1"/></emitter>
      <sensor type="perspective" id="Camera.001"><float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform></sensor></scene>""")
    doc, _ = import_scene(tmp_path / "s.xml", tmp_path / "o1")
    assert [s["name"] for s in doc["shapes"]] == ["Plane_001", "Plane_001-2"]
    assert doc["lights"][0]["name"] == "Point_003" and doc["views"][0]["name"] == "Camera_001"
    assert "Mat_002" in doc["materials"]
    scene_from_dict(doc, source="imported", base=tmp_path / "o1")
    pygltflib = pytest.importorskip("pygltflib")
    import import_testutil as t

    src = t.write_gltf(tmp_path / "g.gltf")
    g = pygltflib.GLTF2().load(str(src))
    g.nodes[0].name, g.nodes[1].name = "Cube", "Cube.001"  # what Blender's glTF exporter writes
    g.save(str(src))
    doc, _ = import_scene(src, tmp_path / "o2")
    assert {"Cube", "Cube_001"} <= {s["name"] for s in doc["shapes"]}
    scene_from_dict(doc, source="imported", base=tmp_path / "o2")


def test_hand_written_dotted_names_are_refused_up_front():
    """In the current format a '.' in a shape or light name is refused at validation, with the fix; an
    older (unversioned) document is migrated instead (scene.migrate renames them, with a warning)."""
    from illumix.scene.spectra import SCHEMA_VERSION

    doc = {"name": "t", "materials": {"m": {"kind": "diffuse", "reflectance": {"value": 0.5}}},
           "shapes": [{"name": "Cube.001", "type": "cube", "material": "m"}],
           "lights": [{"name": "Lamp.1", "type": "point", "position": [0, 2, 0], "group": "g", "strength": 1}],
           "views": [{"name": "v", "origin": [0, 0, 5], "target": [0, 0, 0]}]}
    with pytest.raises(SceneError) as e:
        scene_from_dict({**doc, "schema_version": max(SCHEMA_VERSION, 2)}, source="hand.yaml")
    msg = str(e.value)
    assert "\n" not in msg and "shapes[0] (Cube.001).name" in msg and "'Cube_001'" in msg and "lights[0]" in msg
    with pytest.warns(UserWarning, match="Cube_001"):
        old = scene_from_dict(doc, source="old.yaml")
    assert [s.name for s in old.shapes] == ["Cube_001"]
