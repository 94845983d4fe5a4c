"""Skipping what a scene doesn't need: light groups that send no light into a view are detected by a
cheap pilot (renderer_jobs.mitsuba.light_probe) and recorded as empty in the store instead of rendered."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")

from illumix.cli import main  # noqa: E402
from illumix.scene import demo  # noqa: E402
from illumix.renderer_jobs.mitsuba.light_probe import probe_group  # noqa: E402
from illumix.renderer_jobs.mitsuba.aovs import render_aovs  # noqa: E402
from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube  # noqa: E402
from illumix.scene.load import scene_from_dict  # noqa: E402

RES = (40, 30)


def skip_scene_dict(res=RES) -> dict:
    """Floor and back wall seen by one camera, four groups:
    ``lamp`` — a ceiling panel lighting the view (control); ``boxed`` — a bulb inside a closed cube;
    ``behind`` — a spot behind the camera aimed away from everything; ``pin`` — a 2° spot on a small
    floor patch (a small lit region: the probe must find it)."""
    fm = demo.frame_matrix
    return {
        "name": "skip", "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.7}}},
        "shapes": [
            {"name": "floor", "type": "rectangle", "material": "white",
             "transform": {"matrix": fm((0, 0, 0), (0, 1, 0), (0, 0, -1), (2, 2))}},
            {"name": "back", "type": "rectangle", "material": "white",
             "transform": {"matrix": fm((0, 1, -1), (0, 0, 1), (0, 1, 0), (2, 2))}},
            {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 3.0},
             "transform": {"matrix": fm((0, 1.9, -0.5), (0, -1, 0), (0, 0, -1), (0.4, 0.4))}},
            {"name": "box", "type": "cube", "material": "white",
             "transform": {"scale": 0.15, "translate": (0.5, 0.15, -0.3)}},
        ],
        "lights": [
            {"name": "bulb", "type": "point", "group": "boxed", "position": (0.5, 0.15, -0.3), "strength": 5.0},
            {"name": "away", "type": "spot", "group": "behind", "position": (0, 1, 3), "target": (0, 1.2, 6),
             "strength": 5.0},
            {"name": "pin", "type": "spot", "group": "pin", "position": (-0.6, 1.5, 0.2), "target": (-0.6, 0, 0.2),
             "cutoff_angle": 2.0, "strength": 2.0},
        ],
        "views": [{"name": "cam", "origin": (0, 1, 2.5), "target": (0, 0.7, -1), "fov": 60, "resolution": res}],
        "max_depth": 6,
    }


@pytest.fixture(scope="module")
def scene():
    return scene_from_dict(skip_scene_dict())


def test_probe_finds_dark_and_lit_groups(scene):
    s = RenderSettings(spp=32, seed=3)
    probes = {g: probe_group(scene, "cam", g, s) for g in scene.group_names}
    assert {g: p.lit for g, p in probes.items()} == {"lamp": True, "boxed": False, "behind": False, "pin": True}
    # a dark verdict traced the whole budget (1/16 of the cube's paths); a lit one stopped early
    for g in ("boxed", "behind"):
        assert probes[g].paths == probes[g].budget == -(-RES[0] * RES[1] * 32 // 16)
    assert probes["lamp"].paths < probes["lamp"].budget
    assert probes["lamp"].film == (10, 8) and probes["lamp"].detect_region_px == 48
    # the verdicts are right: the full renders of the dark groups are exactly zero, the others are not
    for g, p in probes.items():
        cube = render_cube(scene, "cam", g, s).cube
        assert (cube.max() > 0) == p.lit, g
    again = probe_group(scene, "cam", "pin", s).to_dict()
    assert {**again, "seconds": 0} == {**probes["pin"].to_dict(), "seconds": 0}  # deterministic


def test_probe_of_demo_room_groups_is_lit_and_cheap():
    room = demo.demo_room(0, resolution=(32, 24))
    for g in room.group_names:
        p = probe_group(room, "front", g, RenderSettings(spp=16))
        assert p.lit and p.paths <= 8 * 6 * 2  # found within the first two chunks


def test_render_skips_dark_groups_into_empty_cubes(tmp_path, capsys):
    from illumix.store import CubeStore

    path = tmp_path / "skip.yaml"
    path.write_text(yaml.safe_dump(json.loads(json.dumps(skip_scene_dict()))))
    out = {}
    for flag in ("--skip-dark", "--no-skip-dark"):
        store = str(tmp_path / flag.strip("-"))
        capsys.readouterr()
        try:
            main(["render", str(path), "--store", store, "--spp", "16", "--json", flag])
        except SystemExit as exc:
            assert exc.code in (0, None)
        summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert sorted(summary["empty"]) == ["skip/cam/behind", "skip/cam/boxed"]
        st = CubeStore.open(store, mode="r")
        metas = {g: st.cube_meta("skip", "cam", g) for g in ("lamp", "boxed", "behind", "pin")}
        assert [g for g, m in metas.items() if m.empty] == ["boxed", "behind"]
        assert np.all(st.read_cube("skip", "cam", "boxed") == 0)
        out[flag] = (st.read_cube("skip", "cam", "lamp"), metas)
    skipped = out["--skip-dark"][1]
    assert skipped["boxed"].render_stats["skipped"] == "dark"
    assert skipped["boxed"].render_stats["probe"]["lit"] is False
    assert "probe" in skipped["lamp"].render_stats
    # without the probe the dark groups are rendered in full (and come out all zero)
    assert "skipped" not in out["--no-skip-dark"][1]["boxed"].render_stats
    # the probe changes nothing in the cubes that are rendered
    np.testing.assert_array_equal(out["--skip-dark"][0], out["--no-skip-dark"][0])


def test_background_pixels_are_skipped_only_where_exactly_zero():
    """Pixels no camera ray of which can hit geometry get no paths when the group has no sky: the
    full render is exactly zero there, and elsewhere the two renders agree within noise."""
    from illumix.renderer_jobs.mitsuba.view_coverage import covered_pixels

    d = skip_scene_dict((48, 36))
    d["views"].append({"name": "high", "origin": (0.4, 1.6, 2.5), "target": (0, 1.4, -1), "up": (0.1, 1, 0),
                       "fov": 50, "resolution": (48, 36)})
    d["lights"].append({"name": "sky", "type": "constant", "group": "sky", "strength": 0.2})
    scene = scene_from_dict(d)
    for view in ("cam", "high"):
        hit = render_aovs(scene, view, RenderSettings(aov_spp=32))["depth"] > 0
        cov = covered_pixels(scene, view)
        assert cov is not None and not np.any(hit & ~cov) and (~cov).sum() > 0.2 * cov.size
    skip = render_cube(scene, "high", "lamp", RenderSettings(spp=32, seed=1, wavelengths="stratified"))
    full = render_cube(scene, "high", "lamp", RenderSettings(spp=32, seed=2, skip_background=False,
                                                             wavelengths="stratified"))
    out = ~covered_pixels(scene, "high")
    assert skip.stats["background_pixels_skipped"] == out.sum() > 0
    assert full.stats["background_pixels_skipped"] == 0
    # all-bands paths need no skip: a background sample is one missed ray, exactly zero
    bands = render_cube(scene, "high", "lamp", RenderSettings(spp=32, seed=3))
    assert np.all(full.cube[out] == 0) and np.all(skip.cube[out] == 0) and np.all(bands.cube[out] == 0)
    d_ = (skip.cube.sum(-1) - full.cube.sum(-1))[~out]
    assert abs(d_.mean()) < 5 * d_.std() / np.sqrt(d_.size)
    # a group with a sky lights the background: nothing is skipped
    assert render_cube(scene, "high", "sky", RenderSettings(spp=16, wavelengths="stratified")
                       ).stats["background_pixels_skipped"] == 0
    # inside a room the walls surround the camera: every pixel may see geometry
    assert covered_pixels(demo.demo_room(0, resolution=(16, 12)), "front") is None


def test_max_lanes_bounds_every_trace_call_even_below_the_film_size(scene, monkeypatch):
    """``max_lanes`` (the memory bound) holds for the pilot, the adaptive rest and the probe when it is
    smaller than the film (1200 px): no Mitsuba call traces more paths; verdicts and image means
    (5 standard errors of the pixel differences) are those of the unsplit run."""
    from illumix.renderer_jobs.mitsuba.trace import Tracer

    sizes: list[int] = []
    trace = Tracer.trace

    def recording(self, pix, *args, **kwargs):
        sizes.append(len(pix))
        return trace(self, pix, *args, **kwargs)

    monkeypatch.setattr(Tracer, "trace", recording)
    tiny = RenderSettings(spp=64, seed=5, max_lanes=50)  # below the probe's 80 coarse pixels too
    assert {g: probe_group(scene, "cam", g, tiny).lit for g in ("lamp", "boxed")} == {"lamp": True, "boxed": False}
    assert sizes and max(sizes) <= 50
    split = render_cube(scene, "cam", "lamp", RenderSettings(spp=64, seed=5, max_lanes=500))
    assert max(sizes) <= 500
    whole = render_cube(scene, "cam", "lamp", RenderSettings(spp=64, seed=6))
    d = (split.cube.sum(-1) - whole.cube.sum(-1)).ravel()
    assert abs(d.mean()) < 5 * d.std() / np.sqrt(d.size)
