"""Generated rooms with real objects: mesh builders checked against closed-form volumes, every item's
PLY read back by trimesh (valid, closed where it should be, inside its footprint), UVs in metres,
wood grain at its physical size, the new kinds present, every room lit by 2–4 groups, every wall and
every top dressed — all from the generated documents and files, not from the generator's own
bookkeeping."""

from __future__ import annotations

import functools
import math
import re

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from illumix.scenegen import mesh as M
from illumix.scenegen.generate import GeneratorConfig, generate_doc

FAST = GeneratorConfig(probe=False)
STRUCT = re.compile(r"(floor|ceiling|wall)\d+$")


@pytest.fixture(autouse=True, scope="module")
def _mesh_cache(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("ILLUMIX_CACHE", str(tmp_path_factory.mktemp("cache")))
    yield
    mp.undo()


def _closed(m: M.Mesh) -> trimesh.Trimesh:
    t = trimesh.Trimesh(m.v, m.f)  # merges coincident vertices
    assert t.is_watertight and t.is_winding_consistent
    return t


def test_mesh_builders_match_closed_form_volumes():
    a, b, c = 0.3, 0.2, 0.1
    assert _closed(M.box((0, 0, 0), (a, b, c))).volume == pytest.approx(8 * a * b * c, rel=1e-9)
    r = 0.03  # rounded box: Steiner's formula for a box grown by a ball (polygonal: slightly less)
    A, B, C = 2 * (a - r), 2 * (b - r), 2 * (c - r)
    steiner = A * B * C + 2 * (A * B + B * C + C * A) * r + math.pi * (A + B + C) * r ** 2 + 4 / 3 * math.pi * r ** 3
    assert _closed(M.rounded_box((a, b, c), r, 8)).volume == pytest.approx(steiner, rel=5e-3)
    n, rr, h = 24, 0.05, 0.2  # a lathed cylinder is an n-gon prism
    prism = n / 2 * rr ** 2 * math.sin(2 * math.pi / n) * h
    assert _closed(M.lathe([(0, 0), (rr, 0), (rr, h), (0, h)], n, sharp=(1, 2))).volume == pytest.approx(prism, rel=1e-9)
    poly = np.array([(0, 0), (1, 0), (1, 1), (0.5, 0.3), (0, 1)])  # concave
    shoelace = 0.5 * abs(np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1]))
    assert _closed(M.extrude(poly, 0, 0.2)).volume == pytest.approx(shoelace * 0.2, rel=1e-9)
    w, hh, bw, t = 0.5, 0.4, 0.05, 0.02  # a frame of rectangular section
    ring = _closed(M.frame_ring(w, hh, [(0, 0), (bw, 0), (bw, t), (0, t)]))
    assert ring.volume == pytest.approx(t * ((w + 2 * bw) * (hh + 2 * bw) - w * hh), rel=1e-9)
    assert _closed(M.rod((0, 0, 0), (0.1, 0.5, 0.2), 0.02, 16)).volume == pytest.approx(
        8 * 0.02 ** 2 * math.sin(2 * math.pi / 16) * math.sqrt(0.01 + 0.25 + 0.04), rel=1e-9)


def test_triangulate_covers_a_concave_polygon_exactly():
    rng = np.random.default_rng(3)
    for _ in range(10):
        th = np.sort(rng.uniform(0, 2 * np.pi, 14))
        p = np.c_[np.cos(th), np.sin(th)] * rng.uniform(0.3, 1.0, (14, 1))
        tri = M.triangulate(p)
        a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
        areas = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
        shoelace = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
        assert len(tri) == 12 and np.all(areas > 0) and areas.sum() == pytest.approx(shoelace, rel=1e-9)


def _read_ply(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 8: x y z nx ny nz u v) and faces of a scenegen PLY, parsed here from its header."""
    with open(path, "rb") as fh:
        data = fh.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode()
    nv = int(re.search(r"element vertex (\d+)", head).group(1))
    nf = int(re.search(r"element face (\d+)", head).group(1))
    assert re.findall(r"property float (\w+)", head) == ["x", "y", "z", "nx", "ny", "nz", "u", "v"]
    v = np.frombuffer(data, "<f4", nv * 8, end).reshape(nv, 8)
    f = np.frombuffer(data, np.dtype([("n", "u1"), ("i", "<i4", (3,))]), nf, end + nv * 32)
    assert np.all(f["n"] == 3) and end + nv * 32 + nf * 13 == len(data)
    return v, f["i"]


CLOSED = {"cup", "bottle", "box", "table", "coffee_table", "cabinet", "fridge", "oven", "washing_machine", "door", "chair",
          "desk", "curtain", "wall_cabinet"}


@pytest.mark.parametrize("seed", [0, 1])
def test_every_item_mesh_is_valid_and_inside_its_footprint(seed):
    from illumix.scenegen.catalog import CLUTTER, CURTAIN, DOOR, FURNITURE, WALL_CABINET
    from illumix.scenegen.materials import Materials

    rng = np.random.default_rng(seed)
    mats = Materials(rng)
    extra = {"door": lambda *a: DOOR(*a), "curtain": lambda *a: CURTAIN(*a, 1.4, 2.2),
             "wall_cabinet": lambda *a: WALL_CABINET(*a, 1.8, 0.7)}
    for kind, build in {**FURNITURE, **CLUTTER, **extra}.items():
        item = build(rng, mats, kind.replace("_", "-") + "0")
        for s in (s for s in item.shapes if s["type"] == "ply"):
            v, f = _read_ply(s["filename"])
            tm = trimesh.load(s["filename"], process=False)  # the field's reader agrees
            assert np.allclose(tm.vertices, v[:, :3]) and np.array_equal(tm.faces, f)
            assert np.all(np.isfinite(v)) and f.min() >= 0 and f.max() < len(v)
            assert np.allclose(np.linalg.norm(v[:, 3:6], axis=1), 1, atol=1e-3), kind
            assert np.all(trimesh.Trimesh(v[:, :3], f, process=False).area_faces > 0), kind
            half = np.array([item.footprint[0] / 2, item.footprint[1] / 2]) + 1e-3
            assert np.all(np.abs(v[:, [0, 2]]) <= half), kind
            assert v[:, 1].max() <= item.height + 1e-3, kind
            merged = trimesh.Trimesh(v[:, :3], f)
            if kind in CLOSED:
                assert all(b.is_watertight for b in merged.split(only_watertight=False)), kind


def test_texture_coordinates_are_metres():
    from illumix.scenegen.meshparts import Parts

    p = Parts("probe")
    p.add("m", M.bevel_box((0.1, 0.5, 0.0), (0.8, 0.02, 0.3), 0.002))
    v, _ = _read_ply(p.shapes()[0]["filename"])
    top = v[:, 4] > 0.9999  # the flat top (inside the 2 mm bevel): u, v are x, z in metres
    assert np.allclose(v[top, 6], v[top, 0], atol=1e-6) and np.allclose(v[top, 7], v[top, 2], atol=1e-6)
    assert np.ptp(v[top, 6]) == pytest.approx(1.6 - 0.004, abs=1e-5)
    assert np.ptp(v[top, 7]) == pytest.approx(0.6 - 0.004, abs=1e-5)


@functools.cache
def _rooms(n: int) -> dict:
    return {seed: generate_doc(seed, FAST) for seed in range(3000, 3000 + n)}


def test_wood_grain_has_its_physical_size():
    """Grain lines 4–14 mm apart (rings per tile × tiles per metre), on meshes with metric UVs."""
    woods = [m["reflectance"] for d in _rooms(20).values() for m in d["materials"].values()
             if isinstance(m.get("reflectance"), dict) and m["reflectance"].get("pattern") == "wood"]
    assert woods
    for t in woods:
        spacing = 1 / (t["scale"][0] * t["params"]["rings"])
        assert 0.003 <= spacing <= 0.02, t


def test_new_kinds_are_present_and_mostly_meshes():
    kinds, mesh, total = set(), 0, 0
    for d in _rooms(20).values():
        for s in d["shapes"]:
            kinds.add(re.sub(r"\d+$", "", s["name"].split("_")[1 if re.match(r"[cwdt]\d+_", s["name"]) else 0]))
            mesh += s["type"] == "ply"
            total += 1
    want = {"chair", "table", "sofa", "shelf", "cabinet", "fridge", "oven", "washing-machine", "exit", "curtain",
            "clock", "plant", "cup", "bottle", "bowl", "vase", "rug", "frame", "wall-shelf"}
    assert want <= kinds, want - kinds
    assert mesh / total > 0.5


def test_every_room_has_two_to_four_lit_groups():
    """50 rooms (and the seeds that once had only daylight): 2–4 groups, each with an emitter."""
    for seed in [*range(50), 264, 631]:
        d = generate_doc(seed, FAST)
        names = [g["name"] for g in d["light_groups"]]
        assert 2 <= len(names) <= 4, (seed, names)
        for g in names:
            assert any(s.get("emitter", {}).get("group") == g for s in d["shapes"]) or \
                any(light["group"] == g for light in d["lights"]), (seed, g)


def _box(s: dict, bounds) -> tuple[np.ndarray, np.ndarray]:
    if s["type"] == "ply":
        b = bounds(s["filename"])
        m = np.asarray(s["transform"]["matrix"])
        c = np.array([[x, y, z, 1] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]]) @ m.T
    elif s["type"] == "sphere":
        c = np.array([np.asarray(s["center"]) - s["radius"], np.asarray(s["center"]) + s["radius"]])
    elif s["type"] == "cylinder":
        p = np.array([s["p0"], s["p1"]])
        c = np.concatenate([p - s["radius"], p + s["radius"]])
    else:
        m = np.asarray(s["transform"]["matrix"])
        z = (-1, 1) if s["type"] == "cube" else (0,)
        c = np.array([[x, y, zz, 1] for x in (-1, 1) for y in (-1, 1) for zz in z]) @ m.T
    return c[:, :3].min(axis=0), c[:, :3].max(axis=0)


def _objects(doc) -> dict:
    bounds = functools.lru_cache(maxsize=None)(lambda fn: trimesh.load(fn, process=False).bounds)
    out = {}
    for s in doc["shapes"]:
        parts = s["name"].split("_")
        o = "_".join(parts[:2]) if re.match(r"[cwdt]\d+$", parts[0]) else parts[0]
        lo, hi = _box(s, bounds)
        out[o] = (np.minimum(out[o][0], lo), np.maximum(out[o][1], hi)) if o in out else (lo, hi)
    return out


def test_every_wall_and_every_top_is_dressed():
    """Each wall ≥ 0.9 m has something within 25 cm of it (a window, a door, furniture, a picture…);
    each table, desk, cabinet and bookcase has something standing on its top."""
    for seed, d in _rooms(20).items():
        objs = _objects(d)
        walls: dict[int, tuple] = {}
        for s in d["shapes"]:
            m = re.match(r"wall(\d+)_\d+$", s["name"])
            if m:
                n = np.asarray(s["transform"]["matrix"])[:3, 2]
                lo, hi = objs[s["name"].split("_")[0]]
                walls[int(m.group(1))] = (0 if abs(n[0]) > 0.5 else 2, lo, hi)
        for i, (ax, lo, hi) in walls.items():
            other = 2 - ax
            if hi[other] - lo[other] < 0.9:
                continue
            assert any(min(abs(a[ax] - lo[ax]), abs(b[ax] - lo[ax])) < 0.25 and
                       min(b[other], hi[other]) - max(a[other], lo[other]) > 0.05
                       for o, (a, b) in objs.items() if not STRUCT.match(o)), (seed, f"wall{i}")
        for o, (a, b) in objs.items():
            if re.match(r"(table|desk|cabinet|shelf)\d+$", o):
                assert any(p != o and abs(c[1] - b[1]) < 0.006 and min(e[0], b[0]) > max(c[0], a[0])
                           and min(e[2], b[2]) > max(c[2], a[2]) for p, (c, e) in objs.items()), (seed, o)


def test_rooms_are_deterministic_and_validate():
    from illumix.scene.load import scene_from_dict

    d = _rooms(20)[3004]
    assert generate_doc(3004, FAST) == d
    for seed, doc in list(_rooms(20).items())[::4]:
        scene_from_dict(doc, source=f"seed {seed}")  # files exist, spectra resolve
