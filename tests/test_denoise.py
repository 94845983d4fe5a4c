"""Denoising (retarget.denoise): linear in the cube, closer to a known truth, edges kept.

The synthetic scene: two materials (ColorChecker patches and a 50 % gray, as in
tests/synthetic_store.py) under a smooth illumination gradient, with Poisson-like relative noise of
10 % per band (about what one 5 nm band carries at 64 spp, bench/RENDER_PERF.md). Guides are the
exact albedo (broad-band and per band), normal and depth of that scene, as the AOV pass gives them,
and the light's direct part (``dt-irradiance``'s per-group guide).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from illumix.retarget.denoise import DENOISE_METHODS, Guides, denoise, describe, method_params
from illumix.retarget.denoise_methods import DENOISE_CHOICES
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID
from tests.synthetic_store import reflectance_image

H, W = 48, 64
NB = DEFAULT_GRID.n_bands
METHODS = DENOISE_METHODS.names


def _broadband(refl: np.ndarray) -> np.ndarray:
    """RGB albedo AOV: mean reflectance over 600–700, 500–600, 400–500 nm (renderer_jobs.mitsuba.aovs)."""
    wl = DEFAULT_GRID.wavelengths
    return np.stack([refl[..., (wl >= a) & (wl < b)].mean(-1) for a, b in ((600, 700), (500, 600), (400, 500))], -1)


def _guides(refl: np.ndarray, direct: np.ndarray) -> Guides:
    normal = np.zeros((*refl.shape[:2], 3), np.float32)
    normal[..., 2] = 1
    return Guides(albedo=_broadband(refl).astype(np.float32), normal=normal,
                  depth=np.full(refl.shape[:2], 2.0, np.float32), hit=np.ones(refl.shape[:2], bool),
                  emitter=np.zeros(refl.shape[:2], bool), albedo_bands=refl.astype(np.float32),
                  direct=direct.astype(np.float32))


def _scene(rng: np.random.Generator, noise: float = 0.10):
    refl = reflectance_image(H, W)
    x = np.tile(np.linspace(0.3, 1.0, W, dtype=np.float32), (H, 1))
    light = x[..., None] * np.linspace(0.8, 1.2, NB, dtype=np.float32)  # smooth, coloured
    truth = (refl * light).astype(np.float32)
    noisy = (truth * (1 + noise * rng.standard_normal(truth.shape))).astype(np.float32)
    return truth, noisy, _guides(refl, x)


@pytest.mark.parametrize("method", METHODS)
def test_linear_relighting_is_exact(method):
    """denoise(Σ a Φ T) = Σ a Φ denoise(T) per band, to float32 precision (DESIGN.md "Denoising")."""
    rng = np.random.default_rng(1)
    _, t1, guides = _scene(rng)
    if method == "dt-irradiance":  # with pixels left as rendered too (straddle, as with the renderer's boost)
        guides = replace(guides, straddle=rng.random((H, W)) < 0.05)
    t2 = np.roll(t1, 7, axis=1) * rng.uniform(0.2, 2.0, NB).astype(np.float32)  # a second group
    s1, s2 = (rng.uniform(0.0, 3.0, NB).astype(np.float32) for _ in range(2))  # a_g Φ_g / E_g per band
    lhs = denoise(s1 * t1 + s2 * t2, guides, method)
    rhs = s1 * denoise(t1, guides, method) + s2 * denoise(t2, guides, method)
    scale = np.abs(rhs).max()
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=2e-6 * scale)


@pytest.mark.parametrize("method", METHODS)
def test_commutes_with_projection(method):
    """One operator for every band: denoising the cube then projecting to raw = projecting then
    denoising (for a demodulating method: of a cube without reflectance, an illumination cube)."""
    rng = np.random.default_rng(2)
    _, cube, guides = _scene(rng)
    proj = rng.uniform(0, 1, (NB, 3)).astype(np.float32)
    kind = "illumination" if method == "dt-irradiance" else "transport"
    a = denoise(cube, guides, method, kind=kind) @ proj
    b = denoise(cube @ proj, guides, method, kind="illumination")
    np.testing.assert_allclose(a, b, rtol=0, atol=2e-6 * np.abs(b).max())


def test_shadow_edges_stay_sharp_with_the_direct_guide():
    """A shadow's edge on one flat material (the guides' albedo and normal are uniform there): the
    direct-light guide stops ``dt-irradiance`` at it, where ``dt-guides`` (which cannot see it)
    carries light across; with a mixture of two groups that is the R/G error at sunlit patches."""
    rng = np.random.default_rng(7)
    refl = np.full((H, W, NB), 0.5, np.float32)
    sun = np.where(np.arange(W) < W // 2, 1.0, 0.05).astype(np.float32) * np.ones((H, 1), np.float32)
    truth = refl * sun[..., None]
    noisy = (truth * (1 + 0.1 * rng.standard_normal(truth.shape))).astype(np.float32)
    guides = _guides(refl, sun)
    for col in (W // 2 - 1, W // 2):
        own = truth[:, col].mean()
        err_irr = abs(denoise(noisy, guides, "dt-irradiance")[:, col].mean() / own - 1)
        err_dt = abs(denoise(noisy, guides, "dt-guides")[:, col].mean() / own - 1)
        assert err_irr < 0.02, f"column {col}: light crossed the shadow edge by {err_irr:.1%}"
        assert err_dt > 0.1  # the test can tell


def test_demodulation_keeps_fine_texture():
    """A one-pixel checker of two reflectances under smooth light: the albedo-demodulated filter
    averages the irradiance, not the texture, so every pixel keeps its own colour."""
    rng = np.random.default_rng(8)
    red = np.where(DEFAULT_GRID.wavelengths > 580, 0.8, 0.05).astype(np.float32)
    blue = np.where(DEFAULT_GRID.wavelengths < 500, 0.8, 0.05).astype(np.float32)
    checker = ((np.arange(H)[:, None] + np.arange(W)[None, :]) % 2).astype(bool)
    refl = np.where(checker[..., None], red, blue)
    light = np.tile(np.linspace(0.5, 1.0, W, dtype=np.float32), (H, 1))
    truth = refl * light[..., None]
    noisy = (truth * (1 + 0.1 * rng.standard_normal(truth.shape))).astype(np.float32)
    den = denoise(noisy, _guides(refl, light), "dt-irradiance")
    rel = np.abs(den - truth) / truth
    assert np.median(rel) < 0.03 and np.median(np.abs(noisy - truth) / truth) > 0.06


def test_missing_guides_name_the_fix():
    _, cube, g = _scene(np.random.default_rng(9))
    no_direct = Guides(g.albedo, g.normal, g.depth, g.hit, g.emitter, g.albedo_bands)
    with pytest.raises(SpectralError, match="direct-light guide"):
        denoise(cube, no_direct, "dt-irradiance")
    with pytest.raises(SpectralError, match="albedo_bands"):
        denoise(cube, Guides(g.albedo, g.normal, g.depth, g.hit, g.emitter).with_direct(g.direct), "dt-irradiance")
    with pytest.raises(SpectralError, match="kind='illumination'"):
        denoise(cube @ np.ones((NB, 3), np.float32), g, "dt-irradiance")
    with pytest.raises(SpectralError, match="finite"):
        g.with_direct(np.full(g.shape, np.nan))
    with pytest.raises(SpectralError, match="behind-glass guide has shape"):
        g.with_direct(g.direct, np.zeros((H, W + 1), np.float32))
    with pytest.raises(SpectralError, match="behind-glass guide has NaN"):
        g.with_direct(g.direct, np.full(g.shape, -1.0, np.float32))
    with pytest.raises(SpectralError, match="straddle guide"):
        denoise(cube, replace(g, straddle=np.zeros((1, W), bool)), "dt-irradiance")
    out = denoise(cube @ np.ones((NB, 3), np.float32), g, "dt-irradiance", kind="illumination")
    assert out.shape == (H, W, 3)


@pytest.mark.parametrize("method", METHODS)
def test_closer_to_truth(method):
    """A noisy cube with known truth gets closer to it: RMS relative error per band and of the R/G,
    B/G chromaticity of its projection both fall by well over 2× (the noise is 10 % per band)."""
    rng = np.random.default_rng(3)
    truth, noisy, guides = _scene(rng)
    den = denoise(noisy, guides, method)

    def rms(x):
        return float(np.sqrt(np.mean(((x - truth) / truth) ** 2)))

    assert rms(den) < rms(noisy) / 2.5
    proj = np.stack([np.exp(-0.5 * ((DEFAULT_GRID.wavelengths - c) / 40) ** 2) for c in (600, 540, 450)], -1)

    def chroma_err(x):
        r, t = x @ proj, truth @ proj
        cx = np.stack([r[..., 0] / r[..., 1], r[..., 2] / r[..., 1]], -1)
        ct = np.stack([t[..., 0] / t[..., 1], t[..., 2] / t[..., 1]], -1)
        return np.median(np.linalg.norm(cx - ct, axis=-1) / np.linalg.norm(ct, axis=-1))

    assert chroma_err(den) < chroma_err(noisy) / 2.5
    assert abs(den.mean() / truth.mean() - 1) < 0.01  # no bias: weights sum to one


@pytest.mark.parametrize("method", METHODS)
def test_edges_between_materials_do_not_bleed(method):
    """Two materials side by side (red | blue albedo): next to the boundary the denoised spectrum stays
    its own material's (within the noise left), where a plain box blur of the same width would mix."""
    rng = np.random.default_rng(4)
    red = np.where(DEFAULT_GRID.wavelengths > 580, 0.8, 0.05).astype(np.float32)
    blue = np.where(DEFAULT_GRID.wavelengths < 500, 0.8, 0.05).astype(np.float32)
    refl = np.where((np.arange(W) < W // 2)[None, :, None], red, blue) * np.ones((H, 1, 1), np.float32)
    truth = refl.astype(np.float32)
    noisy = (truth * (1 + 0.1 * rng.standard_normal(truth.shape))).astype(np.float32)
    guides = _guides(refl, np.ones((H, W), np.float32))
    den = denoise(noisy, guides, method)
    from scipy.ndimage import uniform_filter

    box = uniform_filter(noisy, size=(1, 9, 1))  # what a guide-blind filter of that reach does
    for col in (W // 2 - 1, W // 2):  # the two columns touching the edge
        own = truth[:, col].mean(0)
        err = np.abs(den[:, col].mean(0) - own).max()
        assert err < 0.03, f"column {col}: colour bled across the material edge by {err:.3f}"
        assert np.abs(box[:, col].mean(0) - own).max() > 0.2  # the test can tell


def test_emitters_and_background_are_kept_apart():
    """A bright emitter pixel neighbouring a surface neither spreads into it nor receives from it."""
    rng = np.random.default_rng(5)
    _, noisy, g = _scene(rng)
    emitter = np.zeros((H, W), bool)
    emitter[10:14, 20:24] = True
    cube = noisy.copy()
    cube[emitter] = 1e4
    guides = Guides(g.albedo, g.normal, g.depth, g.hit, emitter, g.albedo_bands, g.direct)
    for method in METHODS:
        den = denoise(cube, guides, method)
        assert np.abs(den[~emitter]).max() < 10 * np.abs(noisy).max(), method
        np.testing.assert_allclose(den[emitter], 1e4, rtol=1e-4, err_msg=method)



def test_a_lamp_partly_inside_a_surface_pixel_makes_no_halo():
    """The AOVs flag a pixel as emitter by its majority, so the surface pixels around a lamp (or a
    window's sky) carry some of its radiance. dt-irradiance leaves them as rendered and lets nothing
    flow from them into the wall; measured on the demo room's corner view, a halo of 23 % p99.3
    chromaticity error around the window and the ceiling light before (bench/DENOISE.md)."""
    rng = np.random.default_rng(6)
    truth, noisy, g = _scene(rng, noise=0.02)
    emitter = np.zeros((H, W), bool)
    emitter[10:14, 20:24] = True
    cube, want = noisy.copy(), truth.copy()
    cube[emitter] = want[emitter] = 1e4
    ring = np.zeros((H, W), bool)
    ring[9:15, 19:25] = True
    ring &= ~emitter
    cube[ring] += 300.0  # a few per cent of the lamp's area inside each neighbouring pixel
    guides = Guides(g.albedo, g.normal, g.depth, g.hit, emitter, g.albedo_bands, g.direct)
    den = denoise(cube, guides, "dt-irradiance")
    wall = ~(emitter | ring)
    rel = np.abs(den[wall] / truth[wall] - 1)
    assert rel.max() < 0.1, rel.max()  # the 300 would add > 100 % to the wall next to it if it spread
    np.testing.assert_allclose(den[ring], cube[ring], rtol=1e-5)  # left as rendered (no similar neighbour)
    before = denoise(noisy, guides, "dt-irradiance")  # and it stays linear: adding the ring adds itself
    np.testing.assert_allclose(den[wall], before[wall], rtol=1e-5, atol=1e-6)


def test_a_lamps_edge_two_pixels_wide_makes_no_halo():
    """A lamp's edge spills light over two pixels of the ceiling beside it (the corner view's tail
    after the one-pixel ring, bench/DENOISE.md): those pixels are left as rendered too, and nothing
    flows from them into the wall."""
    rng = np.random.default_rng(16)
    truth, noisy, g = _scene(rng, noise=0.02)
    emitter = _box(np.s_[20:24, 30:34])
    spill = _box(np.s_[18:26, 28:36]) & ~emitter
    cube = noisy.copy()
    cube[emitter] = 1e4
    cube[spill] += 300.0
    den = denoise(cube, Guides(g.albedo, g.normal, g.depth, g.hit, emitter, g.albedo_bands, g.direct),
                  "dt-irradiance")
    np.testing.assert_allclose(den[spill], cube[spill], rtol=1e-5)
    wall = ~(emitter | spill)
    assert np.abs(den[wall] / truth[wall] - 1).max() < 0.1


def test_a_caustic_behind_glass_is_left_as_rendered():
    """Glass focuses light into a bright spot inside its own shadow: the direct-light guide is 0 all
    over that shadow, so no guide shows the spot's edges and the filter would spread it. Where the
    behind-glass guide says glass keeps the light, nothing is averaged (each pixel as rendered) and
    nothing flows out into the lit floor around it; without it the spot loses most of its peak."""
    rng = np.random.default_rng(15)
    truth, noisy, g = _scene(rng, noise=0.02)
    shadow = _box(np.s_[16:32, 20:40])
    spot = _box(np.s_[22:26, 28:32])
    direct = np.where(shadow, 0.0, g.direct).astype(np.float32)
    behind = np.where(shadow, g.direct, 0.0).astype(np.float32)  # what the glass keeps from the guide
    cube = noisy.copy()
    cube[shadow] *= 0.2  # dim shadow...
    cube[spot] *= 40.0  # ...with the caustic in it
    plain = g.with_direct(direct)
    old = denoise(cube, plain, "dt-irradiance")
    assert old[spot].mean() < 0.6 * cube[spot].mean()  # the spot spread over the shadow
    den = denoise(cube, plain.with_direct(direct, behind), "dt-irradiance")
    np.testing.assert_allclose(den[shadow], cube[shadow], rtol=1e-5)
    lit = ~_grow(shadow, 2)  # GLASS_MARGIN: one pixel more left as rendered
    assert np.abs(den[lit] / truth[lit] - 1).max() < 0.1
    np.testing.assert_allclose(den[lit], denoise(noisy, plain.with_direct(direct, behind), "dt-irradiance")[lit],
                               rtol=1e-5, atol=1e-6)  # linear: nothing of the spot reaches the lit floor


def test_glass_around_the_light_itself_is_filtered_as_usual():
    """A bulb's envelope or a glazed window: glass keeps the group's light from nearly every pixel.
    That marks no caustic anywhere; leaving the whole frame as rendered (and boosting it) would not
    pay, so beyond GLASS_MAX_COVER of the surface the behind-glass guide changes nothing."""
    from illumix.retarget.denoise import irradiance_classes

    _, cube, g = _scene(np.random.default_rng(16), noise=0.05)
    everywhere = g.with_direct(np.zeros_like(g.direct), g.direct)  # all the light comes through glass
    assert np.array_equal(irradiance_classes(everywhere, 0.01), irradiance_classes(g.with_direct(g.direct), 0.01))
    den = denoise(cube, everywhere, "dt-irradiance")
    assert np.abs(den - cube).max() > 0  # filtered, not left as rendered


def test_metal_and_glass_illumination_is_filtered_among_its_own():
    """An illumination cube holds the light falling on a surface, glass and metal included, which
    the guides describe: there metal and glass are one class (3), smoothed among themselves."""
    from illumix.retarget.denoise import irradiance_classes

    rng = np.random.default_rng(17)
    _, _, g = _scene(rng)
    metal, guides = _specular(g, np.s_[20:44, 30:58])
    assert (irradiance_classes(guides, 0.01, "illumination")[metal & g.hit & ~g.emitter] == 3).all()
    assert (irradiance_classes(guides, 0.01, "transport")[metal & g.hit & ~g.emitter] >= 4).all()
    light = np.full((H, W, 4), 0.3, np.float32) * (1 + 0.1 * rng.standard_normal((H, W, 4))).astype(np.float32)
    den = denoise(light, guides, "dt-irradiance", kind="illumination")
    inner = np.zeros((H, W), bool)
    inner[24:40, 34:54] = True
    assert den[inner].std() < 0.5 * light[inner].std()
    with pytest.raises(SpectralError, match="kind"):
        irradiance_classes(guides, 0.01, "both")


def _grow(mask: np.ndarray, r: int) -> np.ndarray:
    from scipy.ndimage import binary_dilation

    return binary_dilation(mask, np.ones((2 * r + 1, 2 * r + 1), bool))


def test_a_receding_floor_is_averaged_over_a_short_stretch():
    """Up a floor seen at a grazing angle each row spans more floor (here 6 % more depth per row),
    so light that falls off along the floor, and that no guide shows (indirect: the direct guide is
    flat), changes faster per pixel far away. The log-depth channel (σ 0.04) shortens the filter
    there: the bias of the noise-free cube stays under 1.5 % (σ 0.08, the old default: 3.2 %; the
    demo room's p99.3 fell 2.47 → 2.37 % on front, 3.18 → 3.05 % on corner, bench/DENOISE.md)."""
    rows = np.arange(H)[::-1, None]
    depth = np.tile(1.5 * 1.06 ** rows, (1, W)).astype(np.float32)
    light = 1 / (1 + (depth / 1.5) ** 2)  # falls off with the distance along the floor
    refl = np.full((H, W, NB), 0.5, np.float32)
    truth = (refl * light[..., None]).astype(np.float32)
    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 1] = 1
    guides = Guides(np.full((H, W, 3), 0.5, np.float32), normal, depth, np.ones((H, W), bool),
                    np.zeros((H, W), bool), refl, np.ones((H, W), np.float32))
    assert np.abs(denoise(truth, guides, "dt-irradiance") / truth - 1).max() < 0.015


def _box(region: tuple[slice, slice]) -> np.ndarray:
    """An ``(H, W)`` mask, True in ``region`` (``np.s_[y0:y1, x0:x1]``)."""
    mask = np.zeros((H, W), bool)
    mask[region] = True
    return mask


def _specular(g: Guides, box: tuple[slice, slice]) -> tuple[np.ndarray, Guides]:
    """``(mask, guides)``: ``g`` with no diffuse reflectance (metal or glass) in ``box``."""
    mask = _box(box)
    bands = g.albedo_bands.copy()
    bands[mask] = 0.0
    return mask, Guides(g.albedo, g.normal, g.depth, g.hit, g.emitter, bands, g.direct)


def test_metal_and_glass_do_not_mix_with_diffuse_surfaces():
    """No diffuse reflectance (albedo_bands 0: metal, glass) means ``cube / floor`` is on another
    scale (100× at the 0.01 floor): such pixels never mix with diffuse ones (left as rendered)."""
    rng = np.random.default_rng(7)
    truth, noisy, g = _scene(rng, noise=0.02)
    metal, guides = _specular(g, np.s_[30:40, 40:56])
    cube = noisy.copy()
    cube[metal] = 0.5  # a bright specular reflection
    den = denoise(cube, guides, "dt-irradiance")
    near = np.zeros((H, W), bool)
    near[26:44, 36:60] = True
    near &= ~metal
    assert np.abs(den[near] / truth[near] - 1).max() < 0.1
    np.testing.assert_allclose(den[metal], 0.5, rtol=1e-4)


def test_metal_and_glass_are_left_as_rendered():
    """What a metal or glass pixel shows is the rest of the scene, reflected or refracted, which no
    guide describes: a refracted pattern is not smoothed (it was, filtered among its own kind)."""
    rng = np.random.default_rng(8)
    _, noisy, g = _scene(rng, noise=0.02)
    glass, guides = _specular(g, np.s_[20:44, 30:58])
    cube = noisy.copy()
    yy, xx = np.indices((H, W))
    cube[glass] = (0.2 + 0.15 * np.sin(xx / 1.5) * np.cos(yy / 2.0))[glass][:, None]  # a refracted image
    den = denoise(cube, guides, "dt-irradiance")
    np.testing.assert_allclose(den[glass], cube[glass], rtol=1e-5)


def test_a_pixel_straddling_a_geometric_edge_is_left_as_rendered():
    """A box's front (depth 2.0, in a shadow no guide shows: the direct guide is flat) before a lit
    wall (depth 2.6). The pixels of column 31 are 90 % box, 10 % wall: their averaged depth is the
    box's within σ_depth, so the filter averages them with the box and loses most of the wall's
    share of their light (3 % off; the goal's p99.3 is 2.5 %). The ``straddle`` AOV (their rays hit
    two surfaces) leaves them as rendered; the pure pixels on both sides are still averaged and
    unbiased."""
    refl = np.full((H, W, NB), 0.5, np.float32)
    share = np.clip(np.arange(W, dtype=np.float32) - 30.9, 0.0, 1.0)  # wall's share: 0.1 in column 31
    light = 0.4 * (1 - share) + 1.0 * share
    depth = np.tile(2.0 * (1 - share) + 2.6 * share, (H, 1)).astype(np.float32)
    truth = np.broadcast_to(refl * light[None, :, None], (H, W, NB)).astype(np.float32)
    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 2] = 1
    flat = Guides(np.full((H, W, 3), 0.5, np.float32), normal, depth, np.ones((H, W), bool), np.zeros((H, W), bool),
                  refl, np.ones((H, W), np.float32))
    straddle = _box(np.s_[:, 31:32])
    fixed = Guides(flat.albedo, normal, depth, flat.hit, flat.emitter, refl, flat.direct, straddle=straddle)
    assert np.abs(denoise(truth, flat, "dt-irradiance")[:, 31] / truth[:, 31] - 1).max() > 0.02  # without it
    den = denoise(truth, fixed, "dt-irradiance")
    np.testing.assert_allclose(den[:, 31], truth[:, 31], rtol=1e-5)
    np.testing.assert_allclose(den[:, ~straddle[0]], truth[:, ~straddle[0]], rtol=1e-4)


def test_registry_names_params_and_errors():
    assert DENOISE_METHODS.canonical("DT") == "dt-guides" == DENOISE_METHODS.canonical("Domain Transform")
    assert DENOISE_CHOICES.canonical("off") == "none"
    rec = describe("dt")
    assert rec["method"] == "dt-guides" and rec["linear"] and rec["params"]["sigma_spatial"] > 0
    with pytest.raises(SpectralError, match="did you mean"):
        method_params("dt-guide")
    with pytest.raises(SpectralError, match="no parameter"):
        method_params("dt", sigma=3)
    with pytest.raises(SpectralError, match="positive"):
        method_params("dt", sigma_spatial=-1)
    _, cube, guides = _scene(np.random.default_rng(6))
    with pytest.raises(SpectralError, match="does not match"):
        denoise(cube[:10], guides)
    bad = cube.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(SpectralError, match="NaN"):
        denoise(bad, guides)
    with pytest.raises(SpectralError, match="AOVs"):
        Guides.from_aovs({"albedo": guides.albedo})


def test_the_renderer_stores_copies_made_with_the_default_method():
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.retarget.denoise_methods import DEFAULT_METHOD

    assert RenderSettings().denoise == DEFAULT_METHOD == "dt-irradiance"
