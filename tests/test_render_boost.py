"""Targeted extra paths (:mod:`renderer_jobs.mitsuba.boost_paths`): more paths where ``dt-irradiance`` cannot
average, chosen from the guides alone.

Independent checks: the reach of a pixel no neighbour resembles is ~1 and of a flat wall small
(closed forms of a box average: white noise averaged over n pixels keeps 1/√n); the extra pass is
an estimator of the same cube as Mitsuba's film render (mean over the boosted pixels within noise of
a 1024-spp full render); pixels outside the mask are bit for bit a render without the option; the
same seed gives the same cube. Renders are tiny (24×16, 16 spp).
"""

from __future__ import annotations

import numpy as np
import pytest

from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.schema import SceneError
from illumix.retarget.denoise import Guides

RES = (24, 16)


def flat_guides(h: int = 32, w: int = 48) -> Guides:
    """A flat grey wall facing the camera, evenly lit."""
    normal = np.zeros((h, w, 3), np.float32)
    normal[..., 2] = 1.0
    return Guides(albedo=np.full((h, w, 3), 0.5, np.float32), normal=normal, depth=np.full((h, w), 2.0, np.float32),
                  hit=np.ones((h, w), bool), emitter=np.zeros((h, w), bool),
                  albedo_bands=np.full((h, w, 63), 0.5, np.float32), direct=np.ones((h, w), np.float32))


def test_reach_is_one_where_no_neighbour_resembles_and_small_on_a_flat_wall():
    from illumix.renderer_jobs.mitsuba.boost_paths import boost_mask, reach

    g = flat_guides()
    normal = g.normal.copy()
    normal[10, 20] = [0.0, 1.0, 0.0]  # one pixel facing up: no neighbour like it
    g = Guides(g.albedo, normal, g.depth, g.hit, g.emitter, g.albedo_bands, g.direct)
    r = reach(g, "dt-irradiance")
    assert r.shape == (32, 48) and r.dtype == np.float32
    # the isolated pixel keeps its own noise: RMS of 32 unit normals (chi, sd ≈ 1/√64 = 0.125)
    assert 0.6 < r[10, 20] < 1.4
    # a flat wall averages ~(2·sigma_spatial)² pixels: far below the threshold
    assert np.median(r) < 0.3
    mask = boost_mask(g, "dt-irradiance", 0.7)
    assert mask[10, 20] and mask.sum() == 1
    assert np.array_equal(r, reach(g, "dt-irradiance"))  # a fixed noise image: guides alone decide
    with pytest.raises(ValueError, match="dt-irradiance"):
        reach(g, "dt-guides")


def test_settings_default_on_with_dt_irradiance_off_otherwise_and_checked():
    assert RenderSettings().boost_factor == 8 and RenderSettings().boost_reach == 0.6
    assert RenderSettings(denoise=None).boost_factor == 1
    assert RenderSettings(denoise="dt-guides").boost_factor == 1
    assert RenderSettings(wavelengths="stratified").boost_factor == 1
    assert RenderSettings(boost_factor=1).boost_factor == 1
    assert RenderSettings(**RenderSettings(boost_factor=3).to_dict()).boost_factor == 3  # survives the job payload
    for kw, msg in (({"boost_factor": 0}, "whole number >= 1"), ({"boost_factor": 2.5}, "whole number"),
                    ({"boost_reach": 0.0}, r"\(0, 1\]"), ({"boost_reach": 1.2}, r"\(0, 1\]"),
                    ({"boost_factor": 2, "denoise": "none"}, "dt-irradiance"),
                    ({"boost_factor": 2, "wavelengths": "stratified"}, "all-bands")):
        with pytest.raises(SceneError, match=msg):
            RenderSettings(**kw)


pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")


@pytest.fixture(scope="module")
def renders():
    from test_render import box_scene

    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.scene.load import scene_from_dict

    box = scene_from_dict(box_scene())
    mask = np.zeros(RES[::-1], bool)
    mask[4:12, 6:18] = True  # a block: the block-mean noise test below needs a rectangle
    s = RenderSettings(spp=16, seed=3, resolution=RES)
    plain = mr.render_cube(box, "cam", "lamp", s)
    boosted = mr.render_cube(box, "cam", "lamp", s, boost_mask=mask)
    again = mr.render_cube(box, "cam", "lamp", s, boost_mask=mask)
    ref = mr.render_cube(box, "cam", "lamp", RenderSettings(spp=1024, seed=9, resolution=RES, boost_factor=1))
    return {"mask": mask, "plain": plain, "boosted": boosted, "again": again, "ref": ref}


def test_unmasked_pixels_are_bit_identical_and_the_seed_fixes_the_cube(renders):
    m, p, b = renders["mask"], renders["plain"], renders["boosted"]
    assert np.array_equal(p.cube[~m], b.cube[~m]) and np.array_equal(p.illumination[~m], b.illumination[~m])
    assert not np.array_equal(p.cube[m], b.cube[m])
    assert np.array_equal(b.cube, renders["again"].cube)
    assert np.array_equal(b.illumination, renders["again"].illumination)
    tp = b.stats["targeted_paths"]
    assert tp["pixels"] == m.sum() and tp["paths_per_pixel"] == 8 * 16
    assert tp["extra_paths_fraction"] == pytest.approx(7 * m.mean(), abs=1e-4)
    assert b.renderer["settings"]["targeted_paths"]["spp_factor"] == 8
    assert "targeted_paths" not in p.stats and p.renderer["settings"]["targeted_paths"] is None


def test_the_extra_pass_estimates_the_film_renders_cube(renders):
    """The extra paths alone, backed out of the path-count-weighted mean
    ``(n0·base + Σ extra)/(n0 + n1)`` (the base is the plain render, bit-identical film), agree with
    a 1024-spp full render over the boosted block within noise, for both cubes; and the boosted
    pixels are closer to it than the plain ones (8× the paths: ~1/√8 of the noise)."""
    from test_render import assert_same_within_noise

    p, b, ref = renders["plain"], renders["boosted"], renders["ref"]
    n0, n1 = 4, 28  # per band set: 16 spp over 4 sets; 7 × that extra
    for kind in ("cube", "illumination"):
        base, comb, r = (getattr(x, kind).astype(np.float64)[4:12, 6:18] for x in (p, b, ref))
        extra = ((n0 + n1) * comb - n0 * base) / n1
        assert_same_within_noise(extra, r, block=2)
        err_b, err_p = np.abs(comb - r).mean(), np.abs(base - r).mean()
        assert err_b < 0.75 * err_p, (kind, err_b, err_p)


def test_a_mask_of_another_size_is_a_clear_error():
    from test_render import box_scene

    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.scene.load import scene_from_dict

    with pytest.raises(SceneError, match="boost mask"):
        mr.render_cube(scene_from_dict(box_scene()), "cam", "lamp", RenderSettings(spp=16, resolution=RES),
                       boost_mask=np.ones((RES[1], RES[0] + 1), bool))


def test_the_film_is_weighted_by_the_paths_the_sampler_rendered(monkeypatch):
    """Multijitter renders 35 paths of the 32 a band set asks for (128 spp over 4 sets). With the
    extra paths' sums forced to zero, a boosted pixel is exactly the film's estimate × 35 / (35 + 7 × 32):
    the film is weighted by what it rendered, not by what was asked."""
    from test_render import box_scene

    from illumix.renderer_jobs.mitsuba import band_render as mb
    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.scene.load import scene_from_dict

    box = scene_from_dict(box_scene())
    s = RenderSettings(spp=128, seed=3, resolution=RES)
    mask = np.zeros(RES[::-1], bool)
    mask[5:9, 8:14] = True
    plain = mr.render_cube(box, "cam", "lamp", s)
    assert plain.stats["samples_per_band_rendered"] == 35
    monkeypatch.setattr(mb, "extra_path_sums", lambda ms, sensor, integrator, pix, *a: np.zeros(
        (len(pix), len(integrator.aov_names()))))
    boosted = mr.render_cube(box, "cam", "lamp", s, boost_mask=mask)
    for kind in ("cube", "illumination"):
        np.testing.assert_allclose(getattr(boosted, kind)[mask], getattr(plain, kind)[mask] * 35 / (35 + 7 * 32),
                                   rtol=1e-5, atol=1e-9)


def test_a_cube_job_traces_the_direct_guide_once_and_records_the_boost(tmp_path, monkeypatch):
    from test_render import box_scene

    from illumix.renderer_jobs.mitsuba import denoise_guides as dg
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.scene.load import scene_from_dict
    from illumix.store import CubeStore

    calls = []
    real = dg.direct_guide
    monkeypatch.setattr(dg, "direct_guide", lambda *a, **k: calls.append(a[2]) or real(*a, **k))
    box = jobs.apply_resolution(scene_from_dict(box_scene()), RES)
    store = str(tmp_path / "st")
    settings = RenderSettings(spp=16, resolution=RES, skip_dark=False)
    execute(jobs.plan([box], store, groups=["lamp"]), store, settings)
    assert calls == ["lamp"]
    meta = CubeStore.open(store, mode="r").cube_meta(box.name, "cam", "lamp")
    tp = meta.render_stats["targeted_paths"]
    assert tp["paths_per_pixel"] == 128 and tp["pixels"] > 0 and 0 < tp["pixel_fraction"] < 1  # some, not all
    passes = meta.denoised.model_extra["guide_passes"]["direct"]
    assert passes["samples_per_pixel"] == 2 * dg.DIRECT_SAMPLES and passes["behind_glass"] is False
    kept = meta.denoised.model_extra["as_rendered_fraction"]  # what is served as rendered, and by which rule
    assert set(kept) == {"transport", "illumination"} and all(0 < v < 1 for v in kept.values())
    assert "noise" in meta.denoised.model_extra["tolerance"]  # the box has no glass
