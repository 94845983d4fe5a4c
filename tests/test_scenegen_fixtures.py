"""Light fixtures built so that they do not make fireflies (bench/SCENES.md, "Fireflies"): battens
emit from a flat diffuser with nothing behind it, cove strips stand off their wall and face into the
room, translucent shades glow outward with their share of the lamp's power — each checked from the
shape documents and the PLY files (trimesh), not from the generator's own bookkeeping."""

from __future__ import annotations

import math

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from illumix.scenegen import fixtures as fx
from illumix.scenegen.materials import Materials
from illumix.scenegen.meshparts import mesh_area
from illumix.scenegen.rooms import make_plan


@pytest.fixture(autouse=True)
def _mesh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ILLUMIX_CACHE", str(tmp_path))


def _frame(shape: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(centre, unit normal, half-extent vectors along local x and y) of a rectangle document."""
    m = np.asarray(shape["transform"]["matrix"], float)
    return m[:3, 3], m[:3, 2] / np.linalg.norm(m[:3, 2]), m[:3, 0], m[:3, 1]


def test_battens_emit_from_a_diffuser_under_a_painted_housing():
    for seed in range(6):
        rng = np.random.default_rng(seed)
        plan, mats = make_plan(rng, "rect"), Materials(rng)
        shapes = fx.tubes(rng, plan, mats, "tubes")
        ems = [s for s in shapes if s.get("emitter")]
        assert ems and all(s["type"] == "rectangle" for s in ems)
        for e in ems:
            c, n, a, b = _frame(e)
            np.testing.assert_allclose(n, [0, -1, 0], atol=1e-9)  # faces straight down
            housing = next(s for s in shapes if s["name"] == e["name"] + "_housing")
            assert mats.docs[housing["material"]]["kind"] == "diffuse"  # painted, not a mirror
            hm = np.asarray(housing["transform"]["matrix"], float)
            lo, hi = hm[:3, 3] - np.abs(hm[:3, :3]).sum(axis=1), hm[:3, 3] + np.abs(hm[:3, :3]).sum(axis=1)
            assert 0 < lo[1] - c[1] < 0.003  # right under the housing: nothing between them to light
            corners = c + np.array([sa * a + sb * b for sa in (-1, 1) for sb in (-1, 1)])
            assert np.all(corners[:, [0, 2]] >= lo[[0, 2]] - 1e-9) and np.all(corners[:, [0, 2]] <= hi[[0, 2]] + 1e-9)


def test_cove_strips_stand_off_their_wall_and_face_the_room():
    found = 0
    for seed in range(12):
        rng = np.random.default_rng(seed)
        plan, mats = make_plan(rng, "rect"), Materials(rng)
        shapes = fx.strips(rng, plan, mats, "strip")
        for e in (s for s in shapes if s.get("emitter")):
            c, n, _, _ = _frame(e)
            # the nearest wall (inward normal) and the strip's distance from it
            dist = [(float(np.dot(np.array([c[0], c[2]]) - np.asarray(w.p0), w.normal)), w) for w in plan.walls
                    if np.dot(np.array([c[0], c[2]]) - np.asarray(w.p0), w.direction) > 0]
            d, wall = min((x for x in dist if x[0] > 0), key=lambda x: x[0])
            assert d == pytest.approx(0.15, abs=1e-6)
            into = float(np.dot(n[[0, 2]], wall.normal))
            assert math.degrees(math.atan2(into, -n[1])) == pytest.approx(45, abs=1e-6)  # 45° off straight down
            found += 1
    assert found


def test_a_fabric_shade_glows_outward_with_its_share_of_the_power():
    found = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        mats = Materials(rng)
        item = fx.floor_lamp(rng, mats, "fl", "lamp")
        glow = next(s for s in item.shapes if "shadeglow" in s["name"])
        t = trimesh.load(glow["filename"], process=False)
        assert mesh_area(glow["filename"]) == pytest.approx(t.area, rel=1e-5)
        # outward: every face normal points away from the lamp's axis (y)
        radial = t.triangles_center * [1, 0, 1]
        assert np.all(np.einsum("ij,ij->i", t.face_normals, radial) > 0)
        disks = [s for s in item.shapes if s.get("emitter") and s["type"] == "disk"]
        p_disks = sum(math.pi * fx.emitting_area(s) * s["emitter"]["strength"] for s in disks)
        p_shade = math.pi * t.area * glow["emitter"]["strength"]
        # the frustum formula the strength is set from vs the 32-gon: within 1 %
        assert p_shade / (p_shade + p_disks) == pytest.approx(fx.SHADE_GLOW, rel=0.01)
        found += 1
    assert found == 40
