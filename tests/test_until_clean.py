"""Render until clean (issue 39): ``RenderSettings.clean_max_spp`` adds paths to a cube while two
independent halves of it disagree as a noisy cube does (renderer_jobs/clean_check.py)."""

from __future__ import annotations

import numpy as np
import pytest
from illumix.renderer_jobs.clean_check import halves_clean, is_clean, measure
from illumix.renderer_jobs.mitsuba.until_clean import render_until_clean
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.schema import SceneError

H, W, B = 40, 50, 3


def _truth() -> np.ndarray:
    y, x = np.mgrid[0:H, 0:W]
    return np.stack([0.2 + 0.01 * x, 0.3 + 0.005 * y, np.full((H, W), 0.25)], -1)


def _fake(firefly_rate: float, halves: bool = True):
    """A render_once stand-in: the truth plus noise ~ 1/√spp and fireflies (one path worth 2000× a
    pixel) at ``firefly_rate`` per pixel per path, independent per seed; its two halves (half the
    paths each) when ``halves``, as the band sets give them; records the calls."""
    calls = []

    def render_once(s, kind="plain"):
        calls.append((s.spp, s.seed))
        rng, t, n = np.random.default_rng(s.seed), _truth(), s.spp / 2

        def half():
            c = t * (1 + rng.normal(0, 0.3 / np.sqrt(n), (H, W, 1)))
            hits = rng.random((H, W)) < firefly_rate * n / 64
            c[hits] += 2000 * t[hits] / n
            return c

        a, b = half(), half()
        cube = (a + b) / 2
        stats = {k: 1.0 for k in ("load_s", "trace_s", "total_s")}
        stats.update({"nonfinite_samples": 0, "paths_per_pixel": s.spp, "samples_per_band": s.spp,
                      "paths_per_pixel_rendered": s.spp, "samples_per_band_rendered": s.spp})
        noise = np.stack([cube.sum(-1), np.full((H, W), 1.0 / s.spp)], -1)
        hv = np.stack([a.sum(-1), b.sum(-1)], -1) if halves else None
        return cube.astype(np.float32), (2 * cube).astype(np.float32), stats, noise.astype(np.float32), hv

    return render_once, calls


def test_a_clean_cube_costs_its_spp():
    render, calls = _fake(firefly_rate=0.0)
    cube, illum, stats, noise = render_until_clean(render, RenderSettings(spp=64, clean_max_spp=1024))
    assert [c[0] for c in calls] == [64]  # one render: its band sets are the halves
    assert stats["until_clean"]["clean"] and stats["until_clean"]["rounds"] == 1 and stats["paths_per_pixel"] == 64
    np.testing.assert_allclose(cube, _truth(), rtol=0.2)
    np.testing.assert_allclose(illum, 2 * cube, rtol=1e-6)
    np.testing.assert_allclose(noise[..., 1], 1 / 64, rtol=1e-6)


def test_without_halves_from_the_sets_two_renders_are_the_halves():
    render, calls = _fake(firefly_rate=0.0, halves=False)
    _, _, stats, noise = render_until_clean(render, RenderSettings(spp=64, clean_max_spp=1024), halves=False)
    assert [c[0] for c in calls] == [32, 32] and len({c[1] for c in calls}) == 2  # two halves, own seeds
    assert stats["until_clean"]["rounds"] == 2 and stats["paths_per_pixel"] == 64
    np.testing.assert_allclose(noise[..., 1], 1 / 64, rtol=1e-6)  # two halves of variance 1/32, averaged
    noisy, calls = _fake(firefly_rate=0.01, halves=False)
    _, _, stats, _ = render_until_clean(noisy, RenderSettings(spp=64, clean_max_spp=256), halves=False)
    assert [c[0] for c in calls] == [32, 32, 32, 32, 64, 64] and not stats["until_clean"]["clean"]


def test_fireflies_buy_more_paths_up_to_the_cap():
    render, calls = _fake(firefly_rate=0.01)
    _, _, stats, _ = render_until_clean(render, RenderSettings(spp=64, clean_max_spp=1024))
    spps = [c[0] for c in calls]
    assert spps == [64, 64, 128, 256, 512][:len(spps)] and len(spps) > 2  # each round doubles the paths
    assert len({c[1] for c in calls}) == len(calls)  # every round its own paths
    assert stats["paths_per_pixel"] == sum(spps) <= 1024 and stats["until_clean"]["rounds"] == len(spps)
    capped, _ = _fake(firefly_rate=0.01)
    _, _, small, _ = render_until_clean(capped, RenderSettings(spp=64, clean_max_spp=128))
    assert small["paths_per_pixel"] == 128 and not small["until_clean"]["clean"]


def test_the_rounds_average_to_an_unbiased_cube():
    """Each round is weighted by its samples: a constant scene comes back exactly."""
    def flat(s, kind="plain"):
        stats = {k: 0.0 for k in ("load_s", "trace_s", "total_s")}
        stats.update({k: s.spp for k in ("nonfinite_samples", "paths_per_pixel", "samples_per_band",
                                         "paths_per_pixel_rendered", "samples_per_band_rendered")})
        c = np.full((H, W, B), 0.5, np.float32)
        hv = np.full((H, W, 2), 1.5)
        hv[0, 0, 0] = 1e3  # a firefly in the same half of every round keeps it "not clean"
        return c, None, stats, None, hv
    cube, illum, stats, noise = render_until_clean(flat, RenderSettings(spp=64, clean_max_spp=256))
    assert illum is None and noise is None and stats["paths_per_pixel"] == 256
    np.testing.assert_allclose(cube, 0.5)


def test_clean_check_definition():
    t = _truth().sum(-1)
    assert is_clean(measure(t, t))
    b = t.copy()
    b[::4, ::4] *= 10  # 6 % of pixels 10:1 apart
    assert not is_clean(measure(t, b)) and not halves_clean(measure(t, b))
    c = t.copy()
    c.ravel()[::70] *= 3.5  # 1.4 % 3.5:1 apart (d = 0.56): too many for two renders, not for two halves
    m = measure(t, c)
    assert 0.01 < m["d_above_0_5"] < 0.02 and not is_clean(m) and halves_clean(m)


@pytest.mark.parametrize("kw, words", [({"clean_max_spp": 32}, "below --spp"),
                                       ({"clean_max_spp": 512, "wavelengths": "stratified"}, "all-bands")])
def test_bad_settings_are_one_line(kw, words):
    with pytest.raises(SceneError, match=words):
        RenderSettings(**kw)


def test_generated_rooms_get_the_rule_by_default():
    """Unset, the cap is 1024 for a generated room rendered all-bands on Mitsuba, 0 (exactly --spp)
    for other scenes, other modes, or halves the band sets cannot split; given, it is what was given."""
    from types import SimpleNamespace as NS
    room, other = NS(generator={"name": "illumix.scenegen", "version": "3", "seed": 1}), NS(generator=None)
    assert RenderSettings().clean_cap(room) == 1024 and RenderSettings().clean_cap(other) == 0
    assert RenderSettings(spp=2048).clean_cap(room) == 2048  # never below --spp
    assert RenderSettings(clean_max_spp=0).clean_cap(room) == 0
    assert RenderSettings(clean_max_spp=256).clean_cap(other) == 256
    assert RenderSettings(spp=16, wavelengths="stratified").clean_cap(room) == 0
    assert RenderSettings(spp=4).clean_cap(room) == 0  # halves of 2 paths do not split into 4 band sets


def test_a_real_cube_renders_in_rounds():
    """Through the renderer (a 32×24 demo cube at 16 spp: noisy, so it adds rounds up to the cap)."""
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.scene.demo import demo_room
    scene = demo_room(0, (32, 24))
    r = render_cube(scene, scene.views[0].name, "desk",
                    RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=False))
    uc = r.stats["until_clean"]
    assert uc["rounds"] >= 2 and 16 <= r.stats["paths_per_pixel"] <= 64
    assert np.isfinite(r.cube).all() and r.cube.shape == (24, 32, scene.spectral_grid.n_bands)


def test_rounds_reuse_the_loaded_scene_with_the_same_pixels():
    """Rounds after the first reuse each pass's loaded Mitsuba scene (sampler set to the round's
    spp): the pixels are those of loading it again for every round."""
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission
    from illumix.scene.demo import demo_room
    scene = demo_room(0, (32, 24))
    view, groups = scene.views[0].name, ["desk"]
    passes, (e, _) = emitter_passes(scene, groups), group_emission(scene, "desk")
    st = RenderSettings(spp=8, clean_max_spp=32, denoise=None, illumination=True)
    loaded: dict = {}
    loaded: dict = {}
    shared = render_until_clean(lambda s, k: render_all_bands(scene, view, groups, passes, s, e, None, loaded, k), st)
    fresh = render_until_clean(lambda s, k: render_all_bands(scene, view, groups, passes, s, e, None, None, k), st)
    assert loaded and shared[2]["until_clean"]["rounds"] == fresh[2]["until_clean"]["rounds"] >= 2
    for a, b in zip(shared[:2] + shared[3:], fresh[:2] + fresh[3:]):
        np.testing.assert_array_equal(a, b)
    # guided rounds (from the third): the guide is learnt once (the first guided round's seed), kept with the
    # scene for the rounds after, and the whole rule is deterministic
    runs = []
    for _ in range(2):
        loaded = {}
        runs.append(render_until_clean(
            lambda s, k: render_all_bands(scene, view, groups, passes, s, e, None, loaded, k), st, guided=True))
        assert ("guide", 0) in loaded and runs[-1][2]["until_clean"]["guided_rounds"] == 1  # the third round
    for a, b in zip(runs[0][:2] + runs[0][3:], runs[1][:2] + runs[1][3:]):
        np.testing.assert_array_equal(a, b)


def test_extra_camera_path_rounds_are_guided_and_weighed_by_their_noise():
    """Through the renderer, light paths off: rounds from the third on learn a guide (its cost and
    cells in the stats), the plain and guided rounds weigh by their measured variance;
    --no-guide-paths renders plain."""
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.scene.demo import demo_room
    scene = demo_room(0, (32, 24))
    st = RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=False, light_paths=False)
    r = render_cube(scene, scene.views[0].name, "desk", st)
    uc = r.stats["until_clean"]
    assert uc["rounds"] == 3 and uc["guided_rounds"] == 1 and 0 < uc["guided_weight"] < 1  # the third round
    assert uc["guide"][0]["guided_cells"] > 0 and uc["guide"][0]["learn_s"] > 0
    assert r.renderer["settings"]["guide_paths"] is True
    off = render_cube(scene, scene.views[0].name, "desk", st.model_copy(update={"guide_paths": False}))
    assert "guided_rounds" not in off.stats["until_clean"] and off.renderer["settings"]["guide_paths"] is False


def test_the_estimate_says_the_rule_can_add_paths():
    from illumix.renderer_jobs.cost_model import Estimate
    plain = Estimate(cpu_s=10, wall_s=8, workers=1, jobs=2, paths=1e6, kernel_s=3)
    capped = Estimate(cpu_s=10, wall_s=8, workers=1, jobs=2, paths=1e6, kernel_s=3, clean_max_factor=16)
    assert "clean-max-spp" not in plain.line() and "up to 16x" in capped.line()


def test_the_estimate_counts_the_rule_on_generated_rooms_only():
    from types import SimpleNamespace as NS
    from illumix.renderer_jobs.cost_model import CLEAN_PATHS_FACTOR, GENERATED_COST_FACTOR, estimate

    def plan(generator):
        view = NS(resolution=(160, 120))
        scene = NS(generator=generator, view=lambda name: view)
        return NS(scenes={"s": scene}, jobs=[NS(scene="s", view="v", group="g", label="s/v/g")])
    room, other = plan({"name": "illumix.scenegen"}), plan(None)
    st = RenderSettings()
    assert estimate(room, st).paths == pytest.approx(CLEAN_PATHS_FACTOR * estimate(other, st).paths)
    assert estimate(room, RenderSettings(clean_max_spp=0)).paths == estimate(other, st).paths
    assert "up to 16x" in estimate(room, st).line() and "until-clean" not in estimate(other, st).line()
    plain = RenderSettings(clean_max_spp=0)  # a generated room's jobs cost more per path: counted as measured
    a, b = estimate(room, plain), estimate(other, plain)
    assert a.cpu_s - a.kernel_s == pytest.approx(GENERATED_COST_FACTOR * (b.cpu_s - b.kernel_s))
