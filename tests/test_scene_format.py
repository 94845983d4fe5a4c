"""The scene format: its published JSON Schema (docs/scene.schema.json) never stale and accepting the
scenes illumix ships; ``schema_version`` checked (newer: one line naming the versions read; older:
migrated); the content hash unchanged by the format's version."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import yaml

from illumix.scene.load import load_scenes, scene_from_dict
from illumix.scene.migrate import CURRENT, MIGRATIONS, SUPPORTED, migrate
from illumix.scene.spectra import SceneError

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "scene.schema.json"

# A scene written by hand; its hash below was computed by illumix before format version 2 (commit
# eb116a6, schema_version 1 and no normal_map field): cubes rendered then must not look stale now.
DOC = {"name": "fmt-test", "description": "hash pin",
       "materials": {"grey": {"kind": "diffuse", "reflectance": {"value": 0.5}},
                     "red": {"kind": "roughplastic",
                             "reflectance": {"wavelengths": [400, 700], "values": [0.1, 0.7]}}},
       "shapes": [{"name": "floor", "type": "rectangle", "material": "grey",
                   "transform": {"scale": 3, "rotate": [{"axis": [1, 0, 0], "angle": -90}]}},
                  {"name": "ball", "type": "sphere", "material": "red", "center": [0, 0.5, 0], "radius": 0.5},
                  {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 3.0},
                   "transform": {"translate": [0, 2.5, 0], "rotate": [{"axis": [1, 0, 0], "angle": 90}]}}],
       "lights": [{"name": "sun", "type": "directional", "group": "daylight", "strength": 2.0,
                   "direction": [0.3, -1, 0.2]}],
       "light_groups": [{"name": "lamp", "emission": "A"}, {"name": "daylight", "kind": "daylight"}],
       "views": [{"name": "v0", "origin": [0, 1.5, 4], "target": [0, 0.5, 0], "resolution": [64, 48]}]}
HASH_BEFORE_V2 = "e49c215f167477a97c339dd0f01696176608b96543298c4e4129c89d7fd424e5"


def _shipped_scenes() -> list[tuple[str, dict]]:
    """Every scene document illumix ships or makes: the example file, the demo room, the validation
    chart, a generated room — as JSON (tuples become arrays, as in a file)."""
    from illumix.scene.demo import demo_room_dict, validation_chart_dict
    from illumix.scenegen.generate import GeneratorConfig, generate_doc

    docs = [("two_lamps.yaml", yaml.safe_load((ROOT / "renderer_jobs/examples/two_lamps.yaml").read_text())),
            ("demo room", demo_room_dict(0, (64, 48), "demo")),
            ("validation chart", validation_chart_dict((64, 48), 0, "flat")),
            ("generated room 3", generate_doc(3, GeneratorConfig(probe=False)))]
    return [(name, json.loads(json.dumps(d))) for name, d in docs]


def test_published_schema_is_the_generated_one():
    from illumix.scene.json_schema import schema_text

    assert SCHEMA_FILE.is_file(), "docs/scene.schema.json is missing: illumix scenes schema --out docs/scene.schema.json"
    assert SCHEMA_FILE.read_text(encoding="utf-8") == schema_text(), (
        "docs/scene.schema.json is stale (the scene model changed): regenerate it with "
        "`illumix scenes schema --out docs/scene.schema.json`")


def test_shipped_scenes_validate_against_the_schema():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    for name, doc in _shipped_scenes():
        errors = [f"{list(e.absolute_path)}: {e.message[:120]}" for e in validator.iter_errors(doc)]
        assert not errors, f"{name}: {errors[:3]}"
    # and what the schema refuses, the loader refuses too: a newer version, a dotted shape name, an unknown field
    for bad in (dict(DOC, schema_version=99), dict(DOC, shapes=[dict(DOC["shapes"][0], name="floor.001")],
                                                    schema_version=CURRENT), dict(DOC, colour="red")):
        assert list(validator.iter_errors(json.loads(json.dumps(bad))))
        with pytest.raises(SceneError):
            scene_from_dict(copy.deepcopy(bad), check=False)


def test_newer_version_is_one_line_naming_the_supported_ones(tmp_path):
    p = tmp_path / "new.yaml"
    p.write_text(yaml.safe_dump(dict(DOC, schema_version=99)))
    with pytest.raises(SceneError) as exc:
        load_scenes(p)
    msg = str(exc.value)
    assert "\n" not in msg and str(p) in msg and "schema_version 99 is newer" in msg
    assert f"versions {', '.join(map(str, SUPPORTED))}" in msg
    for bad in ("2", 0, True, 1.5):
        with pytest.raises(SceneError, match="is not a format version"):
            scene_from_dict(dict(DOC, schema_version=bad), check=False)


def test_cli_refuses_a_newer_version_with_exit_2(tmp_path, capsys):
    from cli_testutil import run_cli

    p = tmp_path / "new.yaml"
    p.write_text(yaml.safe_dump(dict(DOC, schema_version=7)))
    code, out, err = run_cli(capsys, "render", str(p), "--store", str(tmp_path / "st"), "--dry-run")
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "schema_version 7 is newer than this illumix reads (versions 1, 2)" in lines[0]
    assert "Traceback" not in err


def test_version_1_is_migrated_with_a_warning(tmp_path):
    """A version-1 file (here: a Blender-style duplicate 'panel.001' beside a real 'panel_001', and a
    light 'sun.key') loads as version 2 with the dots gone, names unique, nothing else changed."""
    doc = copy.deepcopy(DOC)
    doc["schema_version"] = 1
    doc["shapes"] += [dict(doc["shapes"][2], name="panel_001"), dict(doc["shapes"][2], name="panel.001")]
    doc["lights"][0]["name"] = "sun.key"
    p = tmp_path / "old.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.warns(UserWarning) as caught:
        scene = load_scenes(p)[0]
    said = [str(w.message) for w in caught]
    assert len(said) == 2 and all(m.startswith(f"{p}: format 1 -> 2: ") for m in said)
    assert "shapes: 1 name(s) with '.' renamed ('panel.001' -> 'panel_001-2')" in said[0]
    assert "lights: 1 name(s) with '.' renamed ('sun.key' -> 'sun_key')" in said[1]
    assert scene.schema_version == CURRENT == 2
    assert [s.name for s in scene.shapes] == ["floor", "ball", "panel", "panel_001", "panel_001-2"]
    assert [light.name for light in scene.lights] == ["sun_key"]
    # the migration is a pure function: the input is untouched, and a current document passes unchanged
    again, notes = migrate(doc)
    assert doc["shapes"][-1]["name"] == "panel.001" and again["schema_version"] == CURRENT and len(notes) == 2
    same, notes = migrate(dict(DOC, schema_version=CURRENT))
    assert same == dict(DOC, schema_version=CURRENT) and notes == []
    assert sorted(MIGRATIONS) == list(range(1, CURRENT))  # a step for every older version


def test_unversioned_documents_are_version_1():
    doc = copy.deepcopy(DOC)
    doc["lights"][0]["name"] = "sun.1"
    with pytest.warns(UserWarning, match="format 1 -> 2"):
        scene = scene_from_dict(doc, check=False)
    assert scene.lights[0].name == "sun_1"


def test_content_hash_unchanged_by_the_format_version(tmp_path):
    scene = scene_from_dict(copy.deepcopy(DOC))
    assert scene.scene_hash == HASH_BEFORE_V2
    # written out (now with schema_version: 2) and read back: the same hash
    from illumix.scene.load import dump_scene

    dump_scene(scene, tmp_path / "s.yaml")
    assert yaml.safe_load((tmp_path / "s.yaml").read_text())["schema_version"] == CURRENT
    assert load_scenes(tmp_path / "s.yaml")[0].scene_hash == HASH_BEFORE_V2


def test_cli_prints_the_schema(capsys, tmp_path):
    from cli_testutil import run_cli

    code, out, _ = run_cli(capsys, "scenes", "schema")
    assert code == 0 and json.loads(out) == json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    code, _, _ = run_cli(capsys, "scenes", "schema", "--out", str(tmp_path / "s.json"))
    assert code == 0 and (tmp_path / "s.json").read_text(encoding="utf-8") == out
