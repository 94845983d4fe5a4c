"""Mitsuba backend: variant selection, closed-form validation, relighting, additivity, determinism.

Renders are tiny (≤ 96×64, 16–32 spp). Statistical checks compare a difference of two renders with
the noise of that same difference: pixels are independent (box filter, independent samples), so the
image mean of a difference ``d`` has standard error ``std(d) / √N``; a 5σ bound on three broad
spectral channels fails by chance with probability < 1e-5 for Gaussian noise.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")

from illumix.scene import demo  # noqa: E402
from illumix.renderer_jobs.mitsuba import render as mr  # noqa: E402
from illumix.renderer_jobs.band_schedule import band_counts, live_bands  # noqa: E402
from illumix.renderer_jobs.mitsuba.aovs import render_aovs  # noqa: E402
from illumix.renderer_jobs.mitsuba import scene_dict as ms  # noqa: E402
from illumix.renderer_jobs.mitsuba import variant as mv  # noqa: E402
from illumix.scene.load import scene_from_dict  # noqa: E402
from illumix.scene.schema import SceneError  # noqa: E402

RES = (40, 30)


def box_scene(**group_emission) -> dict:
    """An open box (floor, back and left wall, a ColorChecker) with three light groups:
    ``lamp`` (area light), ``bulb`` (point light), ``sky`` (constant) — all Lambertian, low variance."""
    mats, shapes = demo.colorchecker(center=(0, 1.0, -0.99), normal=(0, 0, 1), patch=0.2, gap=0.03)
    mats.update({"white": {"kind": "diffuse", "reflectance": {"value": 0.7}},
                 "red": {"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "index": 14}}})
    shapes += [
        {"name": "floor", "type": "rectangle", "material": "white",
         "transform": {"matrix": demo.frame_matrix((0, 0, 0), (0, 1, 0), (0, 0, -1), (2, 2))}},
        {"name": "back", "type": "rectangle", "material": "white",
         "transform": {"matrix": demo.frame_matrix((0, 1, -1), (0, 0, 1), (0, 1, 0), (2, 2))}},
        {"name": "left", "type": "rectangle", "material": "red",
         "transform": {"matrix": demo.frame_matrix((-1, 1, 0), (1, 0, 0), (0, 1, 0), (2, 2))}},
        {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 4.0},
         "transform": {"matrix": demo.frame_matrix((0.3, 1.95, -0.3), (0, -1, 0), (0, 0, -1), (0.6, 0.6))}},
    ]
    return {"name": "box", "materials": mats, "shapes": shapes,
            "lights": [{"name": "bulb", "type": "point", "group": "bulb", "position": (-0.5, 1.2, 0.3), "strength": 1.0},
                       {"name": "sky", "type": "constant", "group": "sky", "strength": 0.3}],
            "light_groups": [{"name": g, "emission": group_emission.get(g, "flat")} for g in ("lamp", "bulb", "sky")],
            "views": [{"name": "cam", "origin": (0, 1.0, 2.2), "target": (0, 0.9, -1), "fov": 60, "resolution": RES}],
            "max_depth": 5}


@pytest.fixture(scope="module")
def box():
    return scene_from_dict(box_scene())


def broad(cube: np.ndarray) -> np.ndarray:
    """(H, W, 3) sums over thirds of the bands (a cheap stand-in for camera channels)."""
    return np.stack([c.sum(axis=-1) for c in np.array_split(cube, 3, axis=-1)], axis=-1)


def assert_same_within_noise(a: np.ndarray, b: np.ndarray, k: float = 5.0, block: int = 4) -> None:
    """Image means of ``a`` and ``b`` (broad bands) agree within ``k`` standard errors. The standard
    error comes from ``block``×``block`` block means, not single pixels: quasi-random samplers
    correlate neighbouring pixels' errors a little (measured up to 0.17 for multijitter at 32 spp),
    which a per-pixel estimate would not see."""
    d = broad(a) - broad(b)
    h, w = (d.shape[0] // block) * block, (d.shape[1] // block) * block
    blocks = d[:h, :w].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3)).reshape(-1, 3)
    se = blocks.std(axis=0) / np.sqrt(len(blocks))
    z = blocks.mean(axis=0) / se
    assert np.all(np.abs(z) < k), f"means differ by {z} standard errors"


# ---------------------------------------------------------------------------------------------


def test_find_libllvm_refuses_old_versions(tmp_path):
    for name in ("libLLVM-14.so.1", "libLLVM-15.so", "libLLVM.so.19.1", "libLLVM-17.so", "libLLVMCore.a"):
        (tmp_path / name).write_bytes(b"")
    path, version = mv.find_libllvm(dirs=(str(tmp_path),))
    assert version[0] == 19 and path.endswith("libLLVM.so.19.1")
    (tmp_path / "libLLVM.so.19.1").unlink()
    (tmp_path / "libLLVM-17.so").unlink()
    assert mv.find_libllvm(dirs=(str(tmp_path),)) is None  # 14 and 15 only: refused
    assert mv.llvm_version("/usr/lib/llvm-19/lib/libLLVM.so") == (19,)
    assert mv.llvm_version("/usr/lib/x86_64-linux-gnu/libLLVM-14.0.6.so.1") == (14, 0, 6)


def test_variant_selected_and_llvm_path_set():
    import os

    v = mv.select_variant()
    assert v in mv.VARIANTS
    if v == "llvm_ad_spectral":
        lib = os.environ["DRJIT_LIBLLVM_PATH"]
        assert mv.llvm_version(lib)[0] >= mv.MIN_LLVM


def test_step_spectrum_is_exact_inside_every_band_and_never_all_zero(box):
    """Mitsuba evaluates the tabulated step spectrum at random wavelengths of every band's sampled
    interior (the band minus its guards): exactly the band's value (to float32)."""
    import drjit as dr
    import mitsuba as mi

    assert ms.step_spectrum(np.zeros(63), box) == {"type": "uniform", "value": 0.0}
    assert ms.step_spectrum(np.full(63, 2.0), box) == {"type": "uniform", "value": 2.0}
    d = ms.step_spectrum(np.r_[np.zeros(62), 1.0], box)
    assert d["type"] == "regular" and len(d["values"].split(",")) == 63 * ms.NODES_PER_BAND
    values = np.random.default_rng(0).random(63)
    tex = mi.load_dict(ms.step_spectrum(values, box))
    grid = box.spectral_grid
    g = ms.band_guard(grid.step)
    u = np.random.default_rng(1).random((63, 4))
    lam = grid.edges[:-1, None] + g + (grid.step - 2 * g) * u
    lam[:, 0], lam[:, 1] = grid.edges[:-1] + g, grid.edges[1:] - g  # the interior's own ends too
    si = dr.zeros(mi.SurfaceInteraction3f, 63)
    si.wavelengths = mi.Spectrum(*[mi.Float(lam[:, i].astype(np.float32)) for i in range(4)])
    out = tex.eval(si)
    got = np.stack([np.asarray(out[i]) for i in range(4)], axis=1)
    np.testing.assert_allclose(got, np.repeat(values[:, None], 4, axis=1), rtol=2e-6)


def test_validation_matches_closed_form():
    """Delta light, Lambertian patches, no other geometry, stratified wavelengths: the estimator has
    zero variance, so rendered raw equals closed form to float32 rounding (~1e-6 relative)."""
    from illumix.renderer_jobs.validate import run_validation

    r = run_validation(illuminants=("D65", "FL11", "blackbody:2300"), spp=16, resolution=(96, 64))
    assert len(r.patches) == 72 and {p["patch"] for p in r.patches} == set(range(1, 25))
    for p in r.patches:
        np.testing.assert_allclose(p["raw_rendered"], p["raw_closed_form"], rtol=1e-5)
        assert p["delta_e00"] < 1e-3 and p["relative_rg_bg_pct"] < 1e-3 and p["angular_deg"] < 1e-3
    assert all(s["max_delta_e00"] < 1e-3 for s in r.summary)


def test_stratified_wavelengths_remove_band_count_noise():
    """On the validation chart only the wavelength sampling is random: stratified bands are exact,
    Mitsuba's random wavelengths leave the band-count noise ≈ √((1 − p)/(N p)), p = 4/63, N = spp
    paths: 96 % at 16 spp (× √(E[L²])/E[L] ≈ 1.2 for the spread of patch radiances over the pixels)."""
    from scipy.ndimage import binary_erosion

    scene = demo.validation_chart(resolution=(48, 32))
    out = {}
    for mode in ("stratified", "random"):
        a = mr.render_cube(scene, "head-on", "light", mr.RenderSettings(spp=16, seed=1, wavelengths=mode)).cube
        b = mr.render_cube(scene, "head-on", "light", mr.RenderSettings(spp=16, seed=2, wavelengths=mode)).cube
        lit = binary_erosion(a.mean(-1) > 0.01)
        out[mode] = np.median(np.std(a[lit] - b[lit], axis=0) / np.sqrt(2) / a[lit].mean(axis=0))
    assert out["stratified"] < 1e-5
    assert 0.7 < out["random"] < 1.6


def test_same_seed_same_cube_other_seed_differs(box):
    s = mr.RenderSettings(spp=16, seed=7)
    a = mr.render_cube(box, "cam", "lamp", s)
    b = mr.render_cube(box, "cam", "lamp", s)
    c = mr.render_cube(box, "cam", "lamp", mr.RenderSettings(spp=16, seed=8))
    assert a.cube.shape == (RES[1], RES[0], 63) and a.cube.dtype == np.float32
    assert np.array_equal(a.cube, b.cube)
    assert not np.array_equal(a.cube, c.cube)
    assert a.emission_name == "flat" and np.all(a.emission == 1)
    assert a.renderer["name"] == "mitsuba" and a.renderer["settings"]["wavelength_sampling"] == "all-bands"
    assert a.renderer["settings"]["sampler"] == "multijitter" and a.renderer["settings"]["dispersion"] == "none"
    assert np.all(np.isfinite(a.cube)) and a.cube.min() >= 0


def test_relight_flat_by_fl11_equals_fl11_emission():
    """Linearity per band: a cube rendered with FL11 emission equals the flat cube × FL11̄ — exactly
    (same seed: identical paths) and within noise (another seed)."""
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.relight import band_scales, relight

    flat = scene_from_dict(box_scene())
    fl11 = scene_from_dict(box_scene(lamp="FL11"))
    e = illuminant_spd("FL11")
    t_flat = mr.render_cube(flat, "cam", "lamp", mr.RenderSettings(spp=32, seed=1))
    t_fl11 = mr.render_cube(fl11, "cam", "lamp", mr.RenderSettings(spp=32, seed=1))
    np.testing.assert_allclose(t_fl11.emission, e)
    relit = relight([t_flat.cube], band_scales(e[None], t_flat.emission[None], np.ones(1)))
    np.testing.assert_allclose(t_fl11.cube, relit, rtol=2e-5, atol=1e-7 * relit.max())
    other = mr.render_cube(fl11, "cam", "lamp", mr.RenderSettings(spp=32, seed=2))
    assert_same_within_noise(other.cube, relit)
    # And FL11's spikes survive: the 545 nm band is far brighter than its neighbours.
    i = int(np.argmin(np.abs(flat.spectral_grid.wavelengths - 545)))
    assert other.cube[..., i].mean() > 2 * other.cube[..., i - 3].mean()


def test_groups_add_up_to_all_on(box):
    parts = [mr.render_cube(box, "cam", g, mr.RenderSettings(spp=32, seed=3)).cube for g in box.group_names]
    total = sum(parts)
    all_on = mr.render_cube(box, "cam", None, mr.RenderSettings(spp=32, seed=4)).cube
    assert_same_within_noise(total, all_on)
    # every group contributes (a group missing from the all-on render would fail the test above)
    assert all(p.mean() > 0.02 * total.mean() for p in parts)


def test_aovs(box):
    a = render_aovs(box, "cam", mr.RenderSettings(aov_spp=2))
    h, w = RES[1], RES[0]
    assert a["albedo"].shape == (h, w, 3) and a["normal"].shape == (h, w, 3)
    assert a["depth"].shape == (h, w) and a["mask"].shape == (h, w) and a["mask"].dtype == bool
    m = a["mask"]
    assert 0.3 < m.mean() < 1.0  # the box is open at the top/right: some pixels see the sky
    np.testing.assert_allclose(np.linalg.norm(a["normal"][m], axis=-1), 1, atol=1e-3)
    assert np.all(a["depth"][m] > 0) and np.all(a["depth"][~m] == 0)
    assert 0 <= a["albedo"].min() and a["albedo"].max() <= 1
    # the floor (white 0.7, two-sided diffuse) near the bottom centre
    np.testing.assert_allclose(a["albedo"][h - 2, w // 2], 0.7, atol=1e-3)


def test_narrowband_emission_samples_only_its_bands_and_low_spp_refused():
    """A group emitting 540–560 nm only: its cube is exactly zero elsewhere, the stratified schedule
    spends every sample on the 5 emitting bands (counts exact, none elsewhere), and the lit bands
    equal the flat cube × the emission within noise (per-band image means, 5 standard errors)."""
    d = box_scene()
    d["light_groups"][1]["emission"] = {"wavelengths": [380, 539.9, 540, 560, 560.1, 780],
                                        "values": [0, 0, 1, 1, 0, 0]}
    s = scene_from_dict(d)
    r = mr.render_cube(s, "cam", "bulb", mr.RenderSettings(spp=16, seed=1, wavelengths="stratified"))
    wl = s.spectral_grid.wavelengths
    live = live_bands(r.emission)
    assert wl[live].tolist() == [540, 545, 550, 555, 560]
    assert np.all(r.cube[..., ~((wl >= 537.5) & (wl <= 562.5))] == 0)
    counts = band_counts(12, len(wl), 16, seed=1, live=live)
    assert np.all(counts.sum(axis=1) == 64) and np.all(counts[:, live] >= 12) and counts.sum() == counts[:, live].sum()
    flat = mr.render_cube(scene_from_dict(box_scene()), "cam", "bulb", mr.RenderSettings(spp=64, seed=2))
    bands = mr.render_cube(s, "cam", "bulb", mr.RenderSettings(spp=16, seed=1))  # all-bands: 2 quadruples
    assert bands.stats["quadruples"] == 2 and np.all(bands.cube[..., ~((wl >= 537.5) & (wl <= 562.5))] == 0)
    for cube in (r.cube, bands.cube):
        for b in live:
            x, y = cube[..., b].ravel(), flat.cube[..., b].ravel() * r.emission[b]
            se = np.sqrt(x.var() / x.size + y.var() / y.size)
            assert abs(x.mean() - y.mean()) < 5 * se, (wl[b], x.mean(), y.mean(), se)
    with pytest.raises(SceneError, match="spp >= 2"):      # 5 emitting bands: 4·spp must reach 5
        mr.render_cube(s, "cam", "bulb", mr.RenderSettings(spp=1, wavelengths="stratified"))
    with pytest.raises(SceneError, match="spp >= 16"):     # flat emission: all 63 bands
        mr.render_cube(s, "cam", "lamp", mr.RenderSettings(spp=8, wavelengths="stratified"))


def test_envmap_sky_renders_with_mitsuba_d65_emission(tmp_path):
    """An RGB envmap emits Mitsuba's D65 × its (upsampled) colour: the group's recorded emission is
    that D65, so a grey map of value v at strength s is seen as s·v per unit emission."""
    import mitsuba as mi

    mi.Bitmap(np.full((16, 32, 3), 0.5, dtype=np.float32)).write(str(tmp_path / "sky.exr"))
    d = {"name": "env", "materials": {"g": {"kind": "diffuse", "reflectance": {"value": 0.5}}},
         "shapes": [{"name": "floor", "type": "rectangle", "material": "g",
                     "transform": {"rotate": [{"axis": [1, 0, 0], "angle": -90}]}}],
         "lights": [{"name": "sky", "type": "envmap", "group": "sky", "filename": "sky.exr", "strength": 2.0}],
         "views": [{"name": "v", "origin": [0, 1, 3], "target": [0, 0, 0], "resolution": [32, 24]}]}
    s = scene_from_dict(d, base=tmp_path)
    r = mr.render_cube(s, "v", "sky", mr.RenderSettings(spp=16))
    a = render_aovs(s, "v")
    assert r.emission_name == "mitsuba-d65" and 0.5 < r.emission[0] < r.emission[30]
    seen = r.cube[~a["mask"]].mean(axis=0) / r.emission   # sky seen directly: 2 × 0.5
    np.testing.assert_allclose(seen, 1.0, rtol=0.02)
    d["light_groups"] = [{"name": "sky", "emission": "D65"}]
    with pytest.raises(SceneError, match="envmap"):
        mr.render_cube(scene_from_dict(d, base=tmp_path), "v", "sky", mr.RenderSettings(spp=16))


def test_window_portal_equals_constant_sky_and_lets_the_sun_in():
    """A room open on one side: sun + constant sky, or sun + a portal of the sky's radiance filling
    the opening — the same light enters (exact for a uniform sky), so the cubes agree within noise;
    and the portal does not shadow the sun (it renders in its own pass)."""
    def room(portal: bool) -> dict:
        walls = [((0, 0, 0), (0, 1, 0), (0, 0, -1)), ((0, 2, 0), (0, -1, 0), (0, 0, -1)),
                 ((0, 1, -1), (0, 0, 1), (0, 1, 0)), ((1, 1, 0), (-1, 0, 0), (0, 1, 0)),
                 ((0, 1, 1), (0, 0, -1), (0, 1, 0))]
        shapes = [{"name": f"w{i}", "type": "rectangle", "material": "white",
                   "transform": {"matrix": demo.frame_matrix(c, n, u, (2, 2))}} for i, (c, n, u) in enumerate(walls)]
        lights = [{"name": "sun", "type": "directional", "group": "day", "direction": (0.8, -0.6, 0.0), "strength": 6.0}]
        if portal:  # the open side x = -1, emitting into the room (+x)
            shapes.append({"name": "opening", "type": "rectangle",
                           "emitter": {"group": "day", "strength": 0.5, "portal": True},
                           "transform": {"matrix": demo.frame_matrix((-1, 1, 0), (1, 0, 0), (0, 1, 0), (2, 2))}})
        else:
            lights.append({"name": "sky", "type": "constant", "group": "day", "strength": 0.5})
        return {"name": "room", "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.6}}},
                "shapes": shapes, "lights": lights,
                "views": [{"name": "in", "origin": (0.8, 1.2, 0.8), "target": (-1, 0.6, -0.6), "fov": 80,
                           "resolution": RES}], "max_depth": 5}

    sky = mr.render_cube(scene_from_dict(room(False)), "in", "day", mr.RenderSettings(spp=32, seed=1))
    portal = mr.render_cube(scene_from_dict(room(True)), "in", "day", mr.RenderSettings(spp=32, seed=2))
    assert portal.renderer["settings"]["passes"] == ["without", "only"]
    assert_same_within_noise(sky.cube, portal.cube)
    # the sunlit floor patch is there in both: direct sun alone gives 0.6·6·0.6/π = 0.69 there, while
    # nothing lit by the sky alone exceeds the sky's own radiance 0.5
    assert portal.cube.max() > 0.8 and sky.cube.max() > 0.8
