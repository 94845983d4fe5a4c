"""Illumination cubes (issue 14): independent checks of what the renderer writes beside each
transport cube — closed forms, the transport/albedo identity, the tint of coloured bounce light,
relighting exactness, and the white-Lambertian estimator against demodulation.

Renders are tiny (≤ 96×64, 16–64 spp). Statistical comparisons use the image mean of a difference
against its standard error (pixels are independent), a 5σ bound (see tests/test_render.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")

from test_render import assert_same_within_noise, box_scene  # noqa: E402

from illumix.scene import demo  # noqa: E402
from illumix.renderer_jobs.mitsuba import hero_paths as hero  # noqa: E402
from illumix.renderer_jobs.mitsuba import render as mr  # noqa: E402
from illumix.renderer_jobs.mitsuba.aovs import render_aovs  # noqa: E402
from illumix.scene.load import scene_from_dict  # noqa: E402
from illumix.renderer_jobs.validate import patch_masks  # noqa: E402


def test_white_lambertian_closed_form_on_the_validation_chart():
    """One directional light, Lambertian patches, nothing else: a white Lambertian surface there sends
    E·cosθ/π whatever the patch — exactly (a delta light is sampled without noise), in every band —
    and the transport cube is the patch reflectance times it."""
    s = demo.validation_chart()
    r = mr.render_cube(s, "head-on", "light", mr.RenderSettings(spp=16, seed=1))
    masks = patch_masks(s)
    expect = math.cos(math.radians(30)) / math.pi
    u = np.stack([r.illumination[m].mean(axis=0) for m in masks])  # (24, bands)
    np.testing.assert_allclose(u, expect, rtol=1e-5)
    from illumix.retarget.reflectances import get_reflectances

    _, refl = get_reflectances("ColorChecker N Ohta", s.spectral_grid)
    t = np.stack([r.cube[m].mean(axis=0) for m in masks])
    np.testing.assert_allclose(t / u, refl, rtol=1e-4)
    assert r.stats["illumination"]["traced"] == 0  # all diffuse: demodulated, nothing traced


def _chart_plastic() -> dict:
    doc = demo.validation_chart_dict()
    for m in doc["materials"].values():  # glossy patches: no L/ρ, the estimate is traced
        refl = m.pop("reflectance")
        m.update(kind="roughplastic", reflectance=refl, alpha=0.2)
    return doc


@pytest.mark.parametrize("wavelengths, force, estimator", [
    ("all-bands", None, "in_path"), ("all-bands", "traced", "traced"), ("stratified", None, "traced")])
def test_glossy_estimates_match_the_closed_form_on_glossy_patches(monkeypatch, wavelengths, force, estimator):
    """Rough-plastic patches (no L/ρ): the in-path estimate (all-bands: a white surface along the
    path's own BSDF-sampled continuation), the separate white path, and the stratified mode's traced
    estimate all give the closed form."""
    from illumix.renderer_jobs.mitsuba import bands as mitsuba_bands

    monkeypatch.setattr(hero, "TRACE_BUDGET", 1.0)  # trace every sample: no subsampling noise
    monkeypatch.setattr(mitsuba_bands, "FORCE_FIRST", force)
    s = scene_from_dict(_chart_plastic())
    r = mr.render_cube(s, "head-on", "light", mr.RenderSettings(spp=16, seed=2, wavelengths=wavelengths))
    assert r.stats["illumination"][estimator] > 0 and r.stats["illumination"]["demodulated"] == 0
    u = np.stack([r.illumination[m].mean(axis=0) for m in patch_masks(s)])
    # delta light: the light sample is exact; the continuation escapes (nothing else in the scene)
    np.testing.assert_allclose(u, math.cos(math.radians(30)) / math.pi, rtol=1e-5)
    if wavelengths == "all-bands":
        return
    # small lane blocks: the queue of estimates is traced as it fills (bounded memory), same result
    small = mr.render_cube(s, "head-on", "light", mr.RenderSettings(spp=16, seed=2, max_lanes=4096,
                                                                     wavelengths=wavelengths))
    u = np.stack([small.illumination[m].mean(axis=0) for m in patch_masks(s)])
    np.testing.assert_allclose(u, math.cos(math.radians(30)) / math.pi, rtol=1e-5)


def test_grey_plane_illumination_is_transport_over_albedo_and_tinted_by_a_coloured_wall():
    """The box's white (0.7) floor and back wall beside a red left wall: U = T / 0.7 exactly there
    (the demodulation identity), and near the red wall the illumination is redder than near the
    white one — bounce light carries the wall's colour."""
    box = scene_from_dict(box_scene())
    r = mr.render_cube(box, "cam", "lamp", mr.RenderSettings(spp=64, seed=3))
    a = render_aovs(box, "cam", mr.RenderSettings(aov_spp=16))
    white = np.all(np.abs(a["albedo"] - 0.7) < 1e-6, axis=-1)  # white-material pixels ...
    inner = white.copy()  # ... whose neighbours are too (no path of the pixel hits another material)
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        inner &= np.roll(white, (dy, dx), axis=(0, 1))
    inner[[0, -1]] = inner[:, [0, -1]] = False
    white = inner
    assert white.sum() > 100
    np.testing.assert_allclose(r.cube[white], 0.7 * r.illumination[white], rtol=1e-5, atol=1e-9)
    wl = box.spectral_grid.wavelengths
    red, blue = wl > 600, wl < 490
    h, w = white.shape
    left, right = white.copy(), white.copy()
    left[:, w // 3:] = False  # white surfaces near the red wall (image left)
    right[:, : 2 * w // 3] = False
    ratio = lambda m: r.illumination[m][:, red].mean() / r.illumination[m][:, blue].mean()  # noqa: E731
    assert ratio(left) > 1.15 * ratio(right), (ratio(left), ratio(right))


def test_illumination_relights_exactly_like_transport():
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.relight import band_scales, relight

    flat = mr.render_cube(scene_from_dict(box_scene()), "cam", "lamp", mr.RenderSettings(spp=32, seed=1))
    fl11 = mr.render_cube(scene_from_dict(box_scene(lamp="FL11")), "cam", "lamp", mr.RenderSettings(spp=32, seed=1))
    e = illuminant_spd("FL11")
    relit = relight([flat.illumination], band_scales(e[None], flat.emission[None], np.ones(1)))
    np.testing.assert_allclose(fl11.illumination, relit, rtol=2e-5, atol=1e-7 * relit.max())


def test_illumination_is_finite_non_negative_and_unbiased_against_demodulation(monkeypatch):
    """The box with every surface diffuse: per-sample demodulation (exact) and the other estimators
    (forced on every hit: the stratified mode's traced one; all-bands' in-path and separate white
    path) agree within noise; all finite and ≥ 0."""
    from illumix.renderer_jobs.mitsuba import bands as mitsuba_bands

    box = scene_from_dict(box_scene())
    for wavelengths, forced in (("stratified", ("traced",)), ("all-bands", ("mixed", "traced"))):
        settings = mr.RenderSettings(spp=32, seed=5, wavelengths=wavelengths)
        demod = mr.render_cube(box, "cam", "lamp", settings)
        assert demod.stats["illumination"]["demodulated"] > 0
        for force in forced:
            with monkeypatch.context() as m:
                m.setattr(hero, "RHO_MIN", np.inf)
                m.setattr(hero, "TRACE_BUDGET", 1.0)
                m.setattr(mitsuba_bands, "FORCE_FIRST", force)
                other = mr.render_cube(box, "cam", "lamp", settings)
            for r in (demod, other):
                assert np.isfinite(r.illumination).all() and (r.illumination >= 0).all()
            assert other.stats["illumination"]["demodulated"] == 0
            assert_same_within_noise(other.illumination, demod.illumination)


def test_emitter_aov_flags_the_light_panel():
    box = scene_from_dict(box_scene())
    a = render_aovs(box, "cam", mr.RenderSettings(aov_spp=4))
    assert a["emitter"].dtype == bool and 0 < a["emitter"].sum() < 0.1 * a["emitter"].size
    assert not (a["emitter"] & ~a["mask"]).any()
