"""Generated interiors: valid scenes that load in Mitsuba, reproducible from the seed, distinct across
seeds, with cameras and lights in free space, objects that do not intersect, and views chosen for
mixed light (the probe checked against closed cases)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from illumix.scene.load import scene_from_dict
from illumix.scenegen import GENERATOR_VERSION
from illumix.scenegen.generate import GeneratorConfig, generate_doc, layout_hash

pytest.importorskip("mitsuba")

FAST = GeneratorConfig(probe=False)
SEEDS = range(12)
STRUCTURE = re.compile(r"(floor|ceiling|wall|door|window|rug)\d+$")  # shell, openings, rugs (under furniture)


def _object(name: str) -> str:
    return name.split("_")[0]


def _boxes(scene):
    from illumix.renderer_jobs.mitsuba.scene_dict import shape_hull_points

    out = []
    for s in scene.shapes:
        if scene.is_portal(s):
            continue
        if s.type == "cylinder":  # exact bounds (the hull points pad the ends by the radius)
            p0, p1 = np.asarray(s.p0), np.asarray(s.p1)
            a = (p1 - p0) / np.linalg.norm(p1 - p0)
            r = s.radius * np.sqrt(np.clip(1 - a ** 2, 0, 1))
            out.append((s, np.minimum(p0, p1) - r, np.maximum(p0, p1) + r))
            continue
        p = shape_hull_points(scene, s)
        out.append((s, p.min(axis=0), p.max(axis=0)))
    return out


@pytest.fixture(autouse=True, scope="module")
def _mesh_cache(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("ILLUMIX_CACHE", str(tmp_path_factory.mktemp("cache")))  # generated meshes go here
    yield
    mp.undo()


@pytest.fixture(scope="module")
def rooms(_mesh_cache):
    return {seed: generate_doc(seed, FAST) for seed in SEEDS}


def test_generated_rooms_validate_and_are_reproducible(rooms):
    for seed, doc in rooms.items():
        scene = scene_from_dict(doc, source=f"seed {seed}")
        assert scene.generator == {"name": "illumix.scenegen", "version": GENERATOR_VERSION, "seed": seed}
        assert 2 <= len(scene.group_names) <= 4
        assert 3 <= len(scene.views) <= 7
    assert generate_doc(5, FAST) == rooms[5]
    assert len({layout_hash(d) for d in rooms.values()}) == len(rooms)


def test_layouts_windows_and_fixture_kinds_vary(rooms):
    text = " ".join(d["description"] for d in rooms.values())
    for layout in ("rectangular", "L-shaped", "two rooms"):
        assert layout in text
    groups = {g["name"] for d in rooms.values() for g in d["light_groups"]}
    assert "daylight" in groups and len(groups) >= 5


def test_generated_room_loads_in_mitsuba(rooms):
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene

    scene = scene_from_dict(rooms[1])
    ms, _ = load_mitsuba_scene(scene, scene.views[0].name, None, resolution=(8, 6))
    assert len(ms.shapes()) > 0 and ms.bbox().valid()  # Mitsuba merges shapes: no count to compare


def test_no_camera_inside_an_object_and_all_inside_the_room(rooms):
    for seed, doc in rooms.items():
        scene = scene_from_dict(doc, check=False)
        boxes = _boxes(scene)
        lo_all = np.min([b[1] for b in boxes], axis=0)
        hi_all = np.max([b[2] for b in boxes], axis=0)
        for v in scene.views:
            o = np.asarray(v.origin)
            assert np.all(o > lo_all) and np.all(o < hi_all), (seed, v.name)
            for s, lo, hi in boxes:
                if s.type == "rectangle":
                    continue
                assert not np.all((o > lo - 0.05) & (o < hi + 0.05)), (seed, v.name, s.name)


def test_no_light_inside_furniture_and_no_intersections(rooms):
    for seed, doc in rooms.items():
        scene = scene_from_dict(doc, check=False)
        boxes = [b for b in _boxes(scene) if not STRUCTURE.match(_object(b[0].name))]
        for i, (a, alo, ahi) in enumerate(boxes):
            for b, blo, bhi in boxes[i + 1:]:
                if _object(a.name) == _object(b.name):
                    continue
                overlap = np.minimum(ahi, bhi) - np.maximum(alo, blo)
                assert not np.all(overlap > 2e-3), (seed, a.name, b.name, overlap)


def test_mixed_fraction_closed_cases():
    """Two equal lights mirrored about the view axis: every lit pixel shares 50/50 (fraction 1); one
    group alone: 0."""
    from illumix.scenegen.views import mixed_fractions

    def doc(groups):
        shapes = [{"name": "floor", "type": "rectangle", "material": "w",
                   "transform": {"matrix": [[5, 0, 0, 0], [0, 0, 1, 0], [0, -5, 0, 0], [0, 0, 0, 1]]}}]
        lights = [{"name": f"l{i}", "type": "point", "group": g, "position": [x, 2.0, 0.0], "strength": 5.0}
                  for i, (g, x) in enumerate(zip(groups, (-1.0, 1.0)))]
        return {"name": "probe", "materials": {"w": {"kind": "diffuse", "reflectance": {"value": 0.5}}},
                "shapes": shapes, "lights": lights,
                "views": [{"name": "v", "origin": [0, 3, 0.01], "target": [0, 0, 0], "fov": 40}]}

    both = scene_from_dict(doc(["a", "b"]))
    one = scene_from_dict(doc(["a", "a"]))
    assert mixed_fractions(both, resolution=(24, 18), spp=16)[0] > 0.95
    assert mixed_fractions(one, resolution=(24, 18), spp=16)[0] == 0.0


def test_config_errors_name_the_field():
    with pytest.raises(ValueError, match="layouts"):
        GeneratorConfig(layouts=["round"])
    with pytest.raises(ValueError, match="windows"):
        GeneratorConfig(windows=(2, 5))


def test_clear_views_reject_a_wall_between_camera_and_target():
    """A view 0.5 m in front of a wall with its target behind the wall is not clear; the same view
    turned to the open floor is."""
    from illumix.scenegen.views import clear_views

    wall = {"name": "wall", "type": "rectangle", "material": "w",
            "transform": {"matrix": [[3, 0, 0, 0], [0, 3, 0, 1.5], [0, 0, 1, -0.5], [0, 0, 0, 1]]}}
    floor = {"name": "floor", "type": "rectangle", "material": "w",
             "transform": {"matrix": [[5, 0, 0, 0], [0, 0, 1, 0], [0, -5, 0, 0], [0, 0, 0, 1]]}}
    doc = {"name": "clear", "materials": {"w": {"kind": "diffuse", "reflectance": {"value": 0.5}}},
           "shapes": [wall, floor],
           "lights": [{"name": "l", "type": "point", "group": "a", "position": [0, 2.0, 1.0], "strength": 5.0}],
           "views": [{"name": "blocked", "origin": [0, 1.5, 0], "target": [0, 1.0, -3], "fov": 60},
                     {"name": "open", "origin": [0, 1.5, 0], "target": [0, 0.3, 3], "fov": 60}]}
    scene = scene_from_dict(doc)
    assert clear_views(scene, ["blocked", "open"]).tolist() == [False, True]
