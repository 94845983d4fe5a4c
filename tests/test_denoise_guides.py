"""The renderer's guides of ``dt-irradiance`` (renderer_jobs.mitsuba.denoise_guides) against closed forms:
the per-band albedo AOV is the patches' measured reflectance band by band, the direct-light guide is
E·cosθ/π under a directional light (a delta light: no noise), and the sub-pixel positions stratify
both axes."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")

from illumix.scene import demo  # noqa: E402
from illumix.renderer_jobs.mitsuba import denoise_guides as dg  # noqa: E402
from illumix.renderer_jobs.mitsuba.aovs import render_aovs  # noqa: E402
from illumix.renderer_jobs.mitsuba.render import RenderSettings  # noqa: E402
from illumix.renderer_jobs.validate import patch_masks  # noqa: E402


def test_hammersley_puts_one_point_in_every_row_and_column():
    for n in (16, 64):
        p = dg.hammersley(n)
        assert p.shape == (n, 2) and p.dtype == np.float32 and (p >= 0).all() and (p < 1).all()
        for axis in (0, 1):
            assert sorted(np.floor(p[:, axis] * n).astype(int)) == list(range(n))


def test_guide_wavelengths_follow_the_emission():
    wl = np.arange(395.0, 706.0, 5.0)
    flat = dg.guide_wavelengths(np.ones(63), wl)
    assert flat[0] < 450 and flat[-1] > 650  # spread over the grid
    narrow = np.where(np.abs(wl - 590) <= 10, 1.0, 0.0)  # a sodium-like group
    assert set(dg.guide_wavelengths(narrow, wl)) <= {580.0, 585.0, 590.0, 595.0, 600.0}
    assert len(dg.guide_wavelengths(np.zeros(63), wl)) == 4  # a dark group: still four wavelengths


def test_albedo_bands_and_direct_light_match_the_closed_forms_on_the_validation_chart():
    from illumix.retarget.reflectances import get_reflectances

    s = demo.validation_chart()
    aovs = render_aovs(s, "head-on", RenderSettings(spp=16, seed=1))
    masks = patch_masks(s)
    _, refl = get_reflectances("ColorChecker N Ohta", s.spectral_grid)
    got = np.stack([aovs["albedo_bands"][m].mean(axis=0) for m in masks])  # (24, bands)
    np.testing.assert_allclose(got, refl, rtol=1e-4, atol=1e-6)
    direct = dg.direct_light(s, "head-on", "light", None, seed=3)
    assert direct.shape == aovs["depth"].shape and np.isfinite(direct).all() and (direct >= 0).all()
    expect = math.cos(math.radians(30)) / math.pi  # unit irradiance at 30°, white Lambertian
    for m in masks:
        np.testing.assert_allclose(direct[m], expect, rtol=1e-5)


def test_a_view_stored_without_the_per_band_albedo_gets_it_once(tmp_path):
    """A store written without ``albedo_bands`` and ``straddle`` (``--denoise none``, Cycles, or
    before they existed): the first cube denoised with the default traces them and adds them to the
    view; the next one reads them (the same guides for every group), and both record the
    direct-light pass."""
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.mitsuba.trace import Tracer
    from illumix.store import CubeStore

    s = demo.validation_chart()
    plain = RenderSettings(spp=16, seed=1, denoise=None)
    st = CubeStore.open(str(tmp_path / "store"), mode="a")
    aovs = render_aovs(s, "head-on", plain)
    assert "albedo_bands" not in aovs and "straddle" not in aovs  # not asked for: not traced
    st.write_view(s.name, "head-on", jobs._view_meta(s, "head-on"), aovs)
    settings = RenderSettings(spp=16, seed=1)
    result = render_cube(s, "head-on", "light", settings)
    for k in range(2):
        jobs.store_result(st, s, jobs.Job(s.name, "head-on", "light"), result, settings, overwrite=k > 0, extra_stats={})
        passes = st.cube_meta(s.name, "head-on", "light").denoised.model_extra["guide_passes"]
        assert ("albedo_bands" in passes) == ("straddle" in passes) == (k == 0)
        assert passes["direct"]["samples_per_pixel"] > 0
        assert {"albedo_bands", "straddle"} <= set(st.view_meta(s.name, "head-on").aovs)
    assert st.read_aov(s.name, "head-on", "albedo_bands").shape == (*aovs["depth"].shape, 63)
    np.testing.assert_array_equal(st.read_aov(s.name, "head-on", "straddle"),
                                  dg.straddle(Tracer(s, "head-on", None, None)))


def _box_with_ball(material: str | None) -> object:
    """The test box with a ball (``material``: glass, opaque white, or none) between the point light
    and the floor, so its straight shadow lies on the floor in view."""
    from test_render import box_scene

    from illumix.scene.load import scene_from_dict

    d = box_scene()
    d["materials"]["glass"] = {"kind": "dielectric", "int_ior": 1.5}
    if material is not None:
        d["shapes"].append({"name": "ball", "type": "sphere", "material": material,
                            "center": (-0.3, 0.55, 0.1), "radius": 0.2})
    d["views"][0]["resolution"] = (48, 32)
    return scene_from_dict(d)


def test_behind_glass_is_the_light_the_glass_keeps_from_the_direct_guide():
    """Under a point light (a delta light: no noise) the direct guide plus the light behind glass
    equals the direct guide of the same box without the ball, wherever the camera sees the same
    surface; glass keeps light only inside its own straight shadow, and an opaque ball of the same
    size keeps none 'behind glass' (a plain shadow)."""
    from scipy.ndimage import binary_erosion

    res = (48, 32)
    glass, none, opaque = (_box_with_ball(m) for m in ("glass", None, "white"))
    direct, behind = dg.direct_light(glass, "cam", "bulb", res, seed=1, behind_glass=True)
    np.testing.assert_allclose(direct, dg.direct_light(glass, "cam", "bulb", res, seed=1), rtol=1e-5, atol=1e-7)
    free = dg.direct_light(none, "cam", "bulb", res, seed=1)
    depth = [render_aovs(s, "cam", RenderSettings(spp=16, seed=1, resolution=res, denoise=None))["depth"]
             for s in (glass, none)]
    # not the ball's own pixels, nor their neighbours (the guide's sub-pixel positions differ from the AOVs')
    same = binary_erosion(np.abs(depth[0] - depth[1]) < 1e-4, np.ones((3, 3), bool), border_value=1)
    shadow = same & (behind > 0)
    assert 4 < shadow.sum() < 0.3 * same.sum(), shadow.sum()
    np.testing.assert_allclose((direct + behind)[same], free[same], rtol=1e-4, atol=1e-7)
    full = shadow & (behind >= free - 1e-7)  # pixels wholly in the shadow: no direct light there
    assert full.any() and (direct[full] < 1e-7).all()
    d_opaque, b_opaque = dg.direct_light(opaque, "cam", "bulb", res, seed=1, behind_glass=True)
    assert (b_opaque == 0).all() and (d_opaque[shadow] < free[shadow]).all()


def test_straddle_marks_pixels_whose_rays_hit_two_surfaces():
    """The ``straddle`` AOV flags pixels only at geometric edges — where two walls of the box meet,
    or where its rays partly miss — never inside a flat face; a ball adds a ring around its own
    footprint (measured against the geometry AOVs of the box with and without it)."""
    from scipy.ndimage import binary_dilation, binary_erosion

    from illumix.renderer_jobs.mitsuba.trace import Tracer

    res, k3 = (48, 32), np.ones((3, 3), bool)
    empty, ball = (_box_with_ball(m) for m in (None, "white"))
    aovs = [render_aovs(s, "cam", RenderSettings(spp=16, seed=1, resolution=res, denoise=None, aov_spp=64))
            for s in (empty, ball)]
    flags = [dg.straddle(Tracer(s, "cam", None, res)) for s in (empty, ball)]
    n, hit = aovs[0]["normal"], aovs[0]["mask"]
    # a geometric edge between two adjacent pixels: normals > 25° apart, or one hits and one misses
    edge = np.zeros(res[::-1], bool)
    for a, b in (np.s_[:, :-1], np.s_[:, 1:]), (np.s_[:-1, :], np.s_[1:, :]), (np.s_[:-1, :-1], np.s_[1:, 1:]),\
                (np.s_[:-1, 1:], np.s_[1:, :-1]):
        e = (np.einsum("hwc,hwc->hw", n[a], n[b]) < 0.9) | (hit[a] != hit[b])
        edge[a] |= e
        edge[b] |= e
    near_edge = binary_dilation(edge, k3)
    assert flags[0].dtype == bool and flags[0].shape == res[::-1] and 20 < flags[0].sum() < 0.2 * flags[0].size
    assert not (flags[0] & ~near_edge).any()  # never inside a flat face
    footprint = np.abs(aovs[1]["depth"] - aovs[0]["depth"]) > 1e-4
    ring = footprint & ~binary_erosion(footprint, k3)
    added = flags[1] & ~flags[0]
    assert not (added & ~binary_dilation(footprint, k3)).any()  # only on and around the ball
    assert (added & ring).sum() >= 0.6 * ring.sum()


def test_straddle_is_used_only_with_the_targeted_extra_paths(tmp_path):
    """Without extra paths (``boost_factor`` 1) the pixels ``straddle`` leaves as rendered would keep
    the spp's noise: it is neither traced nor read, even from a view that holds it, and the denoised
    copy's record does not list it."""
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.store import CubeStore

    s = demo.validation_chart()
    boosted, plain = RenderSettings(spp=16, seed=1), RenderSettings(spp=16, seed=1, boost_factor=1)
    assert "straddle" in dg.guides_needed(boosted) and "straddle" not in dg.guides_needed(plain)
    assert "straddle" not in render_aovs(s, "head-on", plain)
    st = CubeStore.open(str(tmp_path / "store"), mode="a")
    st.write_view(s.name, "head-on", jobs._view_meta(s, "head-on"), render_aovs(s, "head-on", boosted))
    job = jobs.Job(s.name, "head-on", "light")
    result = render_cube(s, "head-on", "light", plain)
    for k, (settings, used) in enumerate(((plain, False), (boosted, True))):
        guides, _ = jobs.denoise_guides(st, s, job, settings)
        assert (guides.straddle is not None) == used
        jobs.store_result(st, s, job, result, settings, overwrite=k > 0, extra_stats={})
        assert ("straddle" in st.cube_meta(s.name, "head-on", "light").denoised.guides) == used


def _rays_through_one_pixel(rays: int = 16, spread: float = 0.004) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, direction) (1, rays, 3)``: a pinhole's rays through one pixel's Hammersley positions."""
    xy = (dg.hammersley(rays).astype(np.float64) - 0.5) * spread
    d = np.concatenate([xy, np.ones((rays, 1))], axis=1)
    return np.zeros((1, rays, 3)), (d / np.linalg.norm(d, axis=1, keepdims=True))[None]


def _hits_on(planes: list[tuple[np.ndarray, float]], which: np.ndarray, o: np.ndarray, d: np.ndarray):
    """Normals and distances of rays hitting plane ``which[j]`` of ``planes`` (unit normal n, n·x = c)."""
    n = np.stack([planes[k][0] for k in which])[None]
    t = np.array([planes[k][1] / (planes[k][0] @ d[0, j]) for j, k in enumerate(which)])[None]
    return n, t


def test_straddle_pairs_tell_two_surfaces_from_one_plane_at_a_grazing_angle():
    """The pairwise rule on hits in closed form: two parallel planes 25 % apart in depth, same
    normal (only the tangent-plane test sees them); one plane at a grazing angle, whose depths
    within the pixel spread far more than 5 % (the plane test passes it); one plane seen head-on."""
    o, d = _rays_through_one_pixel()
    back = np.array([0.0, 0.0, -1.0])
    grazing = np.array([0.0, np.cos(np.radians(0.3)), -np.sin(np.radians(0.3))])  # 89.7° from the view
    half = (np.arange(16) >= 8).astype(int)
    cases = {"two parallel planes": ([(back, -2.0), (back, -2.5)], half, True),
             "a grazing plane": ([(grazing, grazing @ np.array([0.0, 0.0, 3.0]))], np.zeros(16, int), False),
             "one plane": ([(back, -2.0)], np.zeros(16, int), False)}
    for name, (planes, which, two) in cases.items():
        n, t = _hits_on(planes, which, o, d)
        assert np.all(t > 0), name
        assert dg._two_surfaces(n, o, d, t)[0] == two, name
        assert dg._on_first_plane(n, o, d, t)[0] == (not two), name
    n, t = _hits_on(cases["a grazing plane"][0], np.zeros(16, int), o, d)
    assert np.log(t.max() / t.min()) > 0.05  # a depth-spread rule would have flagged it


def test_straddle_marks_the_edges_of_patches_floating_before_the_sky():
    """The validation chart's patches hang in front of nothing: their border pixels' rays partly
    miss, the only rule that marks them (same normal, same depth); their insides are never marked."""
    from scipy.ndimage import binary_dilation, binary_erosion

    from illumix.renderer_jobs.mitsuba.trace import Tracer

    s = demo.validation_chart()
    flags = dg.straddle(Tracer(s, "head-on", None, None))
    hit = render_aovs(s, "head-on", RenderSettings(spp=16, seed=1, denoise=None))["mask"]
    inside = np.any([binary_erosion(m, np.ones((3, 3), bool)) for m in patch_masks(s)], axis=0)
    assert flags.sum() > 100 and not (flags & inside).any()
    assert not (flags & ~binary_dilation(~hit, np.ones((3, 3), bool))).any()  # only next to a miss


def test_the_direct_guide_states_its_own_noise():
    """``direct_guide``'s standard error (from two light samples at each position) is what two
    guides traced with other seeds differ by: √2 of it, pixel for pixel on average, under an area
    light; a point light's guide has no sampling noise, and says so."""
    from test_render import box_scene

    from illumix.scene.load import scene_from_dict

    box = scene_from_dict(box_scene())
    res = (32, 24)
    a, b = (dg.direct_guide(box, "cam", "lamp", res, seed=s) for s in (1, 2))
    lit = (a.direct > 0.05 * a.direct.max()) & (a.noise > 0)
    spread = np.sqrt(np.mean((a.direct - b.direct)[lit] ** 2) / 2)
    assert spread == pytest.approx(np.sqrt(np.mean(a.noise[lit] ** 2)), rel=0.25)
    point = dg.direct_guide(box, "cam", "bulb", res, seed=1)
    assert point.noise.max() <= 1e-6 * point.direct.max()


def test_the_guide_as_seen_is_the_guide_on_a_lambertian_chart_and_more_on_a_glossy_one():
    """``seen`` (the light through the surface's own BSDF, per unit diffuse reflectance) equals the
    Lambertian guide on the diffuse validation chart; the same chart made glossy adds a highlight
    on top of it somewhere."""
    s = demo.validation_chart()
    g = dg.direct_guide(s, "head-on", "light", None, seed=3)
    lit = np.logical_or.reduce(patch_masks(s))  # inside the patches (``seen`` is per surface hit, not per pixel area)
    np.testing.assert_allclose(g.seen[lit], g.direct[lit], rtol=1e-4)
    doc = demo.validation_chart_dict()
    for m in doc["materials"].values():
        if m.get("kind") == "diffuse":
            m.update(kind="roughplastic", alpha=0.05)
    from illumix.scene.load import scene_from_dict

    glossy = dg.direct_guide(scene_from_dict(doc), "head-on", "light", None, seed=3)
    assert (glossy.seen[lit] >= 0.5 * glossy.direct[lit]).all() and np.isfinite(glossy.seen).all()


def test_metal_has_no_diffuse_albedo():
    """Mitsuba's ``roughconductor`` answers ``eval_diffuse_reflectance`` with a view-dependent value
    (up to 2.7 on a silver mirror, which the filter then averaged: a blurred reflection); the
    ``albedo_bands`` AOV reads the lobe from the BSDF's flags, so metal is 0 (left as rendered)."""
    from illumix.renderer_jobs.mitsuba.trace import Tracer
    from illumix.scene.load import scene_from_dict

    doc = demo.validation_chart_dict()
    for m in doc["materials"].values():
        m.clear()
        m.update(kind="roughconductor", conductor="Ag", alpha=0.01)
    s = scene_from_dict(doc)
    ab = dg.albedo_bands(Tracer(s, "head-on", None, None), 4)
    assert np.logical_or.reduce(patch_masks(s)).any() and ab.max() == 0
