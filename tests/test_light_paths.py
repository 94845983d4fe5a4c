"""Light paths (renderer_jobs/mitsuba/light_paths.py) against camera paths, and the until-clean
rule's choice between them (issue 39)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from illumix.renderer_jobs.mitsuba.until_clean import next_kind, round_weights  # noqa: E402
from illumix.renderer_jobs.render_settings import RenderSettings  # noqa: E402


def _room() -> dict:
    """A closed white room lit by a panel just below the ceiling facing it (light by a bounce), a
    second panel on the back wall that the camera sees, and a glass ball and a glossy metal
    ball in view: every kind of first vertex light paths must handle or leave to the complement."""
    from illumix.scene import demo

    walls = [("floor", (0, 0, 0), (0, 1, 0), (0, 0, -1)), ("ceiling", (0, 2, 0), (0, -1, 0), (0, 0, 1)),
             ("back", (0, 1, -1), (0, 0, 1), (0, 1, 0)), ("front", (0, 1, 1), (0, 0, -1), (0, 1, 0)),
             ("left", (-1, 1, 0), (1, 0, 0), (0, 1, 0)), ("right", (1, 1, 0), (-1, 0, 0), (0, 1, 0))]
    shapes = [{"name": n, "type": "rectangle", "material": "white",
               "transform": {"matrix": demo.frame_matrix(c, nrm, up, (2, 2))}} for n, c, nrm, up in walls]
    shapes += [{"name": "uplight", "type": "rectangle", "emitter": {"group": "lamp", "strength": 50.0},
                "transform": {"matrix": demo.frame_matrix((0.5, 1.85, -0.5), (0, 1, 0), (0, 0, -1), (0.1, 0.1))}},
               {"name": "sign", "type": "rectangle", "emitter": {"group": "lamp", "strength": 2.0},
                "transform": {"matrix": demo.frame_matrix((-0.5, 1.2, -0.99), (0, 0, 1), (0, 1, 0), (0.4, 0.3))}},
               {"name": "ball", "type": "sphere", "material": "glass", "center": (0.25, 0.45, -0.35), "radius": 0.2},
               {"name": "knob", "type": "sphere", "material": "chrome", "center": (-0.35, 0.35, -0.4), "radius": 0.15},
               {"name": "box", "type": "cube", "material": "plastic",
                "transform": {"matrix": [[0.15, 0, 0, 0.0], [0, 0.15, 0, 0.15], [0, 0, 0.15, 0.2], [0, 0, 0, 1]]}}]
    return {"name": "lightpaths",
            "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.7}},
                          "glass": {"kind": "dielectric", "int_ior": 1.5},
                          "chrome": {"kind": "roughconductor", "conductor": "Cr", "alpha": 0.1},
                          "plastic": {"kind": "roughplastic", "reflectance": {"value": 0.4}, "alpha": 0.2}},
            "shapes": shapes, "lights": [], "light_groups": [{"name": "lamp", "emission": "flat"}],
            "views": [{"name": "cam", "origin": (0, 1.0, 0.9), "target": (0, 0.7, -1), "fov": 70,
                       "resolution": (40, 30)}], "max_depth": 5}


@pytest.fixture(scope="module")
def room():
    from illumix.scene.load import scene_from_dict

    return scene_from_dict(_room())


def _render(scene, kind: str, seed: int, spp: int = 32):
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission

    e = np.asarray(group_emission(scene, "lamp")[0], np.float64)
    st = RenderSettings(denoise=None, seed=seed, spp=spp, clean_max_spp=0)
    return render_all_bands(scene, "cam", ["lamp"], emitter_passes(scene, ["lamp"]), st, e, None, None, kind)


def _first_hits(scene) -> np.ndarray:
    """``(H, W, 3)``: where each pixel's central camera ray first hits the scene."""
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
    from illumix.renderer_jobs.mitsuba.trace import camera_rays
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

    mi, _ = import_mitsuba()
    ms, sensor = load_mitsuba_scene(scene, "cam", ["lamp"], (40, 30))
    n = 40 * 30
    ray = camera_rays(mi, sensor, 40, 30, np.arange(n), np.full((n, 2), 0.5, np.float32),
                      np.full((n, 4), 550.0, np.float32), differential=False)
    p = ms.ray_intersect(ray).p
    return np.stack([np.asarray(p.x), np.asarray(p.y), np.asarray(p.z)], -1).reshape(30, 40, 3)


def _region_means_agree(a: list[np.ndarray], b: list[np.ndarray], mask: np.ndarray, k: float = 6.0) -> None:
    """Region means of two estimators agree within ``k`` standard errors of the seed-to-seed spread."""
    ma = np.array([x[mask].mean() for x in a])
    mb = np.array([x[mask].mean() for x in b])
    se = np.sqrt(ma.var(ddof=1) / len(ma) + mb.var(ddof=1) / len(mb))
    assert abs(ma.mean() - mb.mean()) < k * se + 1e-3 * abs(ma.mean()), (ma, mb)


def test_light_paths_estimate_the_camera_paths_cube_and_illumination(room):
    """Unbiased both: over 4 seeds each, the image means agree within noise (cube and illumination
    cube) and so do the regions light paths cannot connect to — the glass and chrome balls (their
    complement: camera paths through a delta first bounce) and the panel seen directly."""
    from test_render import assert_same_within_noise

    camera = [_render(room, "plain", s) for s in range(1, 5)]
    light = [_render(room, "light", s) for s in range(1, 5)]
    for k in (0, 1):
        assert_same_within_noise(np.mean([r[k] for r in camera], 0), np.mean([r[k] for r in light], 0))
    hit = _first_hits(room)
    masks = {"ball": np.linalg.norm(hit - (0.25, 0.45, -0.35), axis=-1) < 0.21,
             "knob": np.linalg.norm(hit - (-0.35, 0.35, -0.4), axis=-1) < 0.16,
             "sign": (np.abs(hit[..., 2] + 0.99) < 0.005) & (np.abs(hit[..., 0] + 0.5) < 0.15)
             & (np.abs(hit[..., 1] - 1.2) < 0.07)}
    for name, mask in masks.items():
        assert mask.sum() >= 4, name
        for k in (0, 1):
            _region_means_agree([r[k].sum(-1) for r in camera], [r[k].sum(-1) for r in light], mask)
    assert light[0][2]["light_paths"] and not camera[0][2]["light_paths"]
    assert light[0][2]["nonfinite_samples"] == 0


def test_light_paths_are_less_noisy_where_light_arrives_by_a_bounce(room):
    from illumix.renderer_jobs.clean_check import measure

    def rel(kind):
        a, b = (_render(room, kind, s)[0].sum(-1) for s in (7, 8))
        return measure(a, b)["rel"]

    camera, light = rel("plain"), rel("light")
    assert light < 0.8 * camera, (camera, light)


def _fake(spp: int, sd: float) -> tuple:
    h = 1 + np.random.default_rng(int(sd * 1e6) + spp).normal(0, sd, (30, 40, 2))
    return (None, None, {"samples_per_band_rendered": spp}, None, h)


def test_later_rounds_take_the_kind_with_the_least_variance_per_cpu_second():
    """Plain rounds 1 and 2, then half a round of light paths and half of guided ones: the next round
    is of whichever of the two late kinds has the lesser variance × CPU seconds; the plain rounds
    (fewer paths, a flattering variance) do not compete."""
    base = [_fake(64, 0.01), _fake(64, 0.01)]  # plain: quiet and cheap, yet not a candidate
    kinds, cpu = ["plain", "plain", "light", "guided"], [1.0, 1.0, 1.0, 1.0]
    quiet = base + [_fake(64, 0.2), _fake(64, 0.4)]  # light: a quarter of the variance, same CPU
    assert next_kind(quiet, kinds, cpu, "guided") == "light"
    assert next_kind(quiet, kinds, [1.0, 1.0, 5.0, 1.0], "guided") == "guided"  # ... at 5x the CPU
    loud = base + [_fake(64, 0.8), _fake(64, 0.2)]
    assert next_kind(loud, kinds, cpu, "guided") == "guided"
    assert next_kind(quiet + [_fake(128, 0.5)], kinds + ["light"], cpu + [2.0], "guided") == "guided"
    # light paths with fireflies in their halves are not taken, however small their variance
    spiky = [r for r in quiet]
    h = spiky[2][4].copy()
    h[3, 5, 0] = 1e3  # one path worth a thousand pixels in one half
    spiky[2] = (None, None, {"samples_per_band_rendered": 64}, None, h)
    assert next_kind(spiky, kinds, [1.0, 1.0, 1e-6, 1.0], "guided") == "guided"


def test_three_kinds_weigh_inversely_to_their_variance():
    rounds = [_fake(64, 0.2), _fake(64, 0.1), _fake(64, 0.1)]
    w = round_weights(rounds, ["plain", "guided", "light"])
    assert w.sum() == pytest.approx(1)
    assert w[1] == pytest.approx(w[2], rel=0.15) and w[0] == pytest.approx(w[1] / 4, rel=0.15)


def test_the_renderer_takes_light_paths_in_late_rounds_and_can_be_told_not_to():
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.scene.demo import demo_room

    scene = demo_room(0, (32, 24))
    st = RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=True)
    r = render_cube(scene, scene.views[0].name, "desk", st)
    uc = r.stats["until_clean"]
    # spp 16, 16, then the third round split: 16 light, 16 guided (64 in all, the cap)
    assert uc["kinds"] == ["plain", "plain", "light", "guided"] and uc["light_rounds"] == 1
    assert 0 < uc["light_weight"] < 1 and r.stats["paths_per_pixel"] == 64
    assert r.renderer["settings"]["light_paths"] is True and np.isfinite(r.illumination).all()
    off = render_cube(scene, scene.views[0].name, "desk", st.model_copy(update={"light_paths": False}))
    assert off.stats["until_clean"]["kinds"] == ["plain", "plain", "guided"] and off.stats["paths_per_pixel"] == 64
    assert off.renderer["settings"]["light_paths"] is False


def test_a_suns_caustics_are_left_out_as_camera_paths_leave_them_and_its_pass_keeps_to_camera_paths():
    """The sun through a glass ball onto the floor: camera paths cannot find that light, light paths
    would (+3 % on this room) but drop it, so both estimate the same cube. A pass with a light at
    infinity takes camera paths even in a light round (light_paths_reach)."""
    from illumix.renderer_jobs.mitsuba.light_paths import light_paths_reach, light_set_aovs
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
    from illumix.scene.load import scene_from_dict

    d = _room()
    d["shapes"] = [s for s in d["shapes"] if s["name"] not in ("ceiling", "uplight", "sign")]
    d["lights"] = [{"name": "sun", "type": "directional", "group": "lamp", "direction": [0.3, -0.9, -0.2],
                    "strength": 3.0}]
    sunny = scene_from_dict(d)
    ms, sensor = load_mitsuba_scene(sunny, "cam", ["lamp"], (40, 30), flat_emission=True)
    assert not light_paths_reach(ms)
    assert light_paths_reach(load_mitsuba_scene(scene_from_dict(_room()), "cam", ["lamp"], (40, 30))[0])
    grid = sunny.spectral_grid
    from illumix.renderer_jobs.mitsuba.bands import band_quadruples

    bands = np.arange(0, grid.n_bands, 8)
    quads, lanes = band_quadruples(grid.edges, bands)
    on = np.flatnonzero(lanes >= 0)  # light paths and their complement (the glass ball seen directly)
    light = [light_set_aovs(quads, grid.step, sunny.max_depth, False, ms, sensor, 128, s)[..., on].mean() for s in (1, 2, 3)]
    camera = [_render(sunny, "plain", s, 128)[0][..., bands].mean() for s in (1, 2, 3)]
    se = np.sqrt(np.var(light, ddof=1) / 3 + np.var(camera, ddof=1) / 3)
    assert abs(np.mean(light) - np.mean(camera)) < 3 * se, (light, camera)  # the caustic: 8 s.e.


def test_light_paths_are_for_one_group_with_a_lamp_or_a_sun_through_windows(monkeypatch):
    """Lamps, a spot light included, may take light paths; so may the demo's daylight (a sun through
    its window: tests/test_sun_windows.py); no cube of two groups may (not flat emission). A lamp's
    renders held "not clean" reach the rule's late rounds and take a light round."""
    from illumix.renderer_jobs.mitsuba.band_render import light_paths_apply
    from illumix.scene.demo import demo_room

    scene = demo_room(0, (32, 24))
    assert light_paths_apply(scene, ["ceiling"]) and light_paths_apply(scene, ["desk"])
    assert light_paths_apply(scene, ["daylight"])
    assert not light_paths_apply(scene, ["ceiling", "desk"])
    from illumix.renderer_jobs.mitsuba import until_clean
    from illumix.renderer_jobs.mitsuba.render import render_cube

    monkeypatch.setattr(until_clean, "halves_clean", lambda m: False)
    st = RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=False)
    assert "light" in render_cube(scene, scene.views[0].name, "desk", st).stats["until_clean"]["kinds"]
