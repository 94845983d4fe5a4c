"""What makes ``dt-irradiance`` unable to hurt (issue 33, bench/FIDELITY.md): emitter and background
pixels left as rendered, the group's direct light divided out before filtering (ramps become flat),
and the direct-light test that leaves as rendered the pixels where the filter would move the
guide's own light by more than the cube's noise — all from guides and the cube's noise level, so
the filter stays linear. Closed forms on synthetic guides; the renderer's noise estimates against
their definitions."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from illumix.retarget import denoise_classes as dc
from illumix.retarget.denoise import Guides, denoise, irradiance_guide_image, relative_noise, shading
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID

H, W = 48, 64
NB = DEFAULT_GRID.n_bands


def _guides(direct: np.ndarray, emitter: np.ndarray | None = None, hit: np.ndarray | None = None) -> Guides:
    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 2] = 1
    refl = np.full((H, W, NB), 0.5, np.float32)
    return Guides(albedo=np.full((H, W, 3), 0.5, np.float32), normal=normal, depth=np.full((H, W), 2.0, np.float32),
                  hit=np.ones((H, W), bool) if hit is None else hit,
                  emitter=np.zeros((H, W), bool) if emitter is None else emitter,
                  albedo_bands=refl).with_direct(direct.astype(np.float32))


def _isolated(guides: Guides, kind: str = "transport") -> np.ndarray:
    return irradiance_guide_image(guides, 0.05, 0.04, 0.4, 0.01, kind)[..., 0] > 3e4


def test_emitter_and_background_pixels_are_served_as_rendered():
    """A lamp seen in frame spans 100× from its rim to its centre; averaged among its own pixels it
    was inflated (bench/FIDELITY.md: a fixture pixel 180 → 3,727). Now each is its own."""
    rng = np.random.default_rng(0)
    emitter = np.zeros((H, W), bool)
    emitter[5:15, 10:30] = True
    hit = np.ones((H, W), bool)
    hit[30:, 50:] = False  # background (sky)
    g = _guides(np.full((H, W), 1.0), emitter, hit & ~emitter | emitter)
    cube = rng.uniform(0.1, 100.0, (H, W, NB)).astype(np.float32)
    out = denoise(cube, g)
    np.testing.assert_allclose(out[emitter], cube[emitter], rtol=1e-6)  # divided and multiplied back: rounding
    np.testing.assert_allclose(out[~hit], cube[~hit], rtol=1e-6)
    from illumix.retarget.denoise import as_rendered

    kept = as_rendered(g)
    assert kept[emitter].all() and kept[~hit].all() and not kept[40:, 5:40].any()  # a lit flat wall is filtered
    assert as_rendered(g, "dt-guides") is None


def test_the_direct_light_is_divided_out_so_a_ramp_is_kept():
    """A point light's falloff across the frame (light ∝ the guide): with the shading divided out the
    filter sees a nearly flat image (the floor for bounce light keeps a gentle slope), so even at the
    frame's borders, where a normalised filter bends a ramp, the noise-free cube comes back within
    1.5 % (it was bent by 4.5 %, with the albedo alone divided out)."""
    x = np.tile(np.linspace(0.3, 1.0, W, dtype=np.float32), (H, 1))
    g = _guides(x)
    truth = (0.5 * x[..., None] * np.linspace(0.8, 1.2, NB, dtype=np.float32)).astype(np.float32)
    rel = np.abs(denoise(truth, g) / truth - 1)
    assert rel.max() < 0.015
    s = shading(g)
    assert s.shape == (H, W, 1) and (s > 0).all()
    np.testing.assert_allclose(s[..., 0], x + dc_floor(x), rtol=1e-6)


def dc_floor(x: np.ndarray) -> float:
    from illumix.retarget.denoise_shading import SHADE_FLOOR

    return SHADE_FLOOR * float(x.mean())


def test_a_spot_cone_comes_back_within_the_tolerance():
    """A spot's cone on a wall: full inside a radius, falling to nothing over two pixels. Every
    pixel of the noise-free cube comes back within the tolerance of its light (plus the bounce light
    the guide does not show), and those the direct-light test left as rendered exactly."""
    y, x = np.indices((H, W))
    r = np.hypot(x - 30.0, y - 24.0)
    spot = np.clip((14.0 - r) / 2.0, 0.0, 1.0).astype(np.float32)  # 1 inside, 0 outside, a 2-pixel rim
    light = spot + 0.05  # a little bounce light everywhere
    g = _guides(spot)
    truth = (0.5 * light[..., None] * np.ones(NB, np.float32)).astype(np.float32)
    iso = _isolated(g)
    out = denoise(truth, g)
    scale = 0.5 * (spot + dc.DIRECT_FLOOR * spot.mean())
    err = np.abs(out - truth)[..., 0]
    assert (err <= dc.DIRECT_TOLERANCE * scale + 0.5 * 0.05 + 1e-6).all()  # the bounce light is not in the guide
    np.testing.assert_allclose(out[iso], truth[iso], rtol=1e-6)


def test_the_tolerance_follows_the_cube_s_noise():
    """The same cone, with the cube's noise known: a clean cube (0.1 %) leaves more pixels as
    rendered than a noisy one (5 %), and a guide noisier than the cube leaves every lit pixel."""
    y, x = np.indices((H, W))
    spot = np.clip((14.0 - np.hypot(x - 30.0, y - 24.0)) / 6.0, 0.0, 1.0).astype(np.float32)
    g = _guides(spot)
    total = np.full((H, W), 10.0, np.float32)

    def with_noise(rel):
        return g.with_cube_noise(np.stack([total, np.full((H, W), (10.0 * rel) ** 2, np.float32)], -1))

    clean, noisy = (_isolated(with_noise(rel)).sum() for rel in (0.001, 0.05))
    assert clean > noisy and clean > 0
    shaky = replace(with_noise(0.01), direct_noise=np.full((H, W), 0.1, np.float32))  # 10 % guide noise
    assert _isolated(shaky)[spot > 0.5].all()


def test_relative_noise_pools_the_variance():
    total = np.full((H, W), 10.0, np.float32)
    var = np.full((H, W), 4.0, np.float32)
    np.testing.assert_allclose(relative_noise(total, var), 0.2, rtol=1e-5)
    var[20, 20] = 4.0 + 24.0  # one noisy pixel is shared with its 5×5 window
    assert relative_noise(total, var)[20, 22] == pytest.approx(np.sqrt(4.0 + 24.0 / 25) / 10, rel=1e-5)
    with pytest.raises(SpectralError, match="noise"):
        Guides.with_cube_noise(_guides(np.ones((H, W))), np.zeros((H, W, 3)))


def test_the_band_sets_spread_estimates_the_variance_of_their_mean():
    """``set_noise``: k independent estimates of a sum → their mean and ``s²/k``; over many pixels
    its mean is the variance of the mean (σ²/k), unbiased."""
    from illumix.renderer_jobs.mitsuba.band_render import set_noise

    rng = np.random.default_rng(1)
    est = 5.0 + 2.0 * rng.standard_normal((4, 200, 200))
    out = set_noise(est)
    np.testing.assert_allclose(out[..., 0], est.mean(0))
    assert out[..., 1].mean() == pytest.approx(4.0 / 4, rel=0.02)


def test_a_glossy_highlight_is_divided_out_of_a_transport_cube():
    """The group's light as the camera sees it (``direct_seen``) carries a highlight the Lambertian
    guide does not. A transport cube is divided by it, so the noise-free cube with the highlight
    comes back within the tolerance everywhere (with the Lambertian guide alone the filter smeared
    it by over 10 %); an illumination cube (a white Lambertian surface) has no highlight and is
    divided by the Lambertian guide."""
    y, x = np.indices((H, W))
    direct = np.full((H, W), 1.0, np.float32)
    bump = 3.0 * np.exp(-((x - 30.0) ** 2 + (y - 20.0) ** 2) / 8.0).astype(np.float32)
    seen = direct + bump
    truth = (0.5 * seen[..., None] * np.ones(NB, np.float32)).astype(np.float32)
    plain = _guides(direct)
    g = plain.with_direct(direct, seen=seen)
    rel = np.abs(denoise(truth, g) / truth - 1)
    assert rel.max() < 1.5 * dc.DIRECT_TOLERANCE
    assert np.abs(denoise(truth, plain) / truth - 1).max() > 0.1  # the test can tell
    np.testing.assert_allclose(shading(g, "illumination"), shading(plain, "illumination"))
    assert not _isolated(g, "illumination")[seen > 1.5].any()


def test_with_every_new_guide_relighting_stays_exact():
    """The shading, the light as seen, the guide's and the cube's noise all fix the operator before
    the cube is read: ``denoise(Σ s T) = Σ s denoise(T)`` per band, to float32 precision."""
    rng = np.random.default_rng(4)
    y, x = np.indices((H, W))
    spot = np.clip((14.0 - np.hypot(x - 30.0, y - 24.0)) / 3.0, 0.0, 1.0).astype(np.float32)
    g = _guides(spot).with_direct(spot, noise=np.full((H, W), 0.002, np.float32), seen=spot * 1.3)
    g = g.with_cube_noise(np.stack([np.full((H, W), 1.0), rng.uniform(1e-5, 1e-3, (H, W))], -1).astype(np.float32))
    t1 = rng.uniform(0.0, 1.0, (H, W, NB)).astype(np.float32)
    t2 = rng.uniform(0.0, 1.0, (H, W, NB)).astype(np.float32)
    s1, s2 = (rng.uniform(0.0, 3.0, NB).astype(np.float32) for _ in range(2))
    for kind in ("transport", "illumination"):
        lhs = denoise(s1 * t1 + s2 * t2, g, kind=kind)
        rhs = s1 * denoise(t1, g, kind=kind) + s2 * denoise(t2, g, kind=kind)
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=2e-6 * np.abs(rhs).max())


def test_the_frame_sum_is_kept_and_pixels_left_as_rendered_are_untouched():
    """A normalised filter's columns do not sum to 1 where it stops, so it moved a group's frame
    sum (room-4242's floor lamp +0.42 %); the deficit is put back, in proportion to what was divided
    out, over the filtered pixels only. Checked against the plain sums, per band and kind, on a
    scene with a spot's rim, a lamp in frame and texture — and the operator is still linear, and
    keeps a flat irradiance flat (``keep_frame_sum``'s ``rᵀ 1 = 0``)."""
    rng = np.random.default_rng(7)
    y, x = np.indices((H, W))
    spot = np.clip((14.0 - np.hypot(x - 30.0, y - 24.0)) / 3.0, 0.0, 1.0).astype(np.float32) + 0.05
    lamp = np.zeros((H, W), bool)
    lamp[2:6, 50:58] = True
    g = _guides(spot, emitter=lamp)
    g = replace(g, albedo_bands=rng.uniform(0.05, 0.9, (H, W, NB)).astype(np.float32))
    for kind in ("transport", "illumination"):
        cube = (spot[..., None] * (1 + 0.3 * rng.standard_normal((H, W, NB)))).astype(np.float32)
        cube = np.abs(cube * (g.albedo_bands if kind == "transport" else 1.0)).astype(np.float32)
        cube[lamp] = 50.0
        out = denoise(cube, g, kind=kind)
        np.testing.assert_allclose(out.sum(axis=(0, 1), dtype=np.float64), cube.sum(axis=(0, 1), dtype=np.float64),
                                   rtol=2e-6)
        kept = _isolated(g, kind)
        assert kept[lamp].all()
        np.testing.assert_allclose(out[kept], cube[kept], rtol=1e-6)  # x / mod · mod: float32 rounding only
        assert np.abs(out - cube).max() > 0.01  # the filter did filter
    flat = (g.albedo_bands * shading(g)).astype(np.float32)  # a flat irradiance under the shading
    np.testing.assert_allclose(denoise(flat, g), flat, rtol=2e-5, atol=1e-7)
