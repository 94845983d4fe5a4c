"""The all-bands renderer (issue 17): every band on every path, Mitsuba's render loop and samplers.

Independent checks: against the 4-wavelength stratified renderer (a different estimator of the same
cube: image means within noise), the point of the mode (a single band far less noisy at equal spp),
reproducibility across thread counts, band sets that change nothing but the noise, and the settings'
refusals. Renders are tiny (≤ 64×48, ≤ 64 spp); statistical bounds as in tests/test_render.py.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")

from test_render import assert_same_within_noise, box_scene  # noqa: E402

from illumix.renderer_jobs.mitsuba import render as mr  # noqa: E402
from illumix.renderer_jobs.band_schedule import mix_seed  # noqa: E402
from illumix.renderer_jobs.mitsuba.band_render import band_sets, spp_allowed  # noqa: E402
from illumix.renderer_jobs.mitsuba.bands import band_quadruples  # noqa: E402
from illumix.scene.load import scene_from_dict  # noqa: E402
from illumix.scene.schema import SceneError  # noqa: E402


@pytest.fixture(scope="module")
def box():
    return scene_from_dict(box_scene())


def test_band_sets_interleave_and_cover_every_live_band_once():
    live = np.arange(63)
    for per_path, n_sets in ((64, 1), (32, 2), (16, 4), (8, 8), (4, 16)):
        sets = band_sets(live, per_path // 4)
        assert len(sets) == n_sets and all(len(s) <= per_path for s in sets)
        assert sorted(np.concatenate(sets).tolist()) == live.tolist()
        assert all(s[0] < n_sets and s[-1] > 62 - n_sets for s in sets)  # each set spans the spectrum
    quads, lanes = band_quadruples(np.arange(64) * 5.0 + 392.5, np.array([3, 4, 5, 6, 7]))
    assert len(quads) == 2 and lanes.tolist() == [3, 4, 5, 6, 7, -1, -1, -1]
    assert quads[0] == (407.5, 412.5, 417.5, 422.5) and quads[1] == (427.5,) * 4


def test_seeds_never_share_random_numbers_by_construction():
    seen = {mix_seed(s, k, j) for s in range(8) for k in range(3) for j in range(8)}
    assert len(seen) == 8 * 3 * 8


def test_all_bands_agrees_with_the_stratified_renderer_and_its_bands_are_far_cleaner(box):
    """Two estimators of the same cube: image means within noise. At the same spp a single band
    (550 nm) of the all-bands cube (64 bands per path) is several times less noisy: every path
    carries it, instead of 4 of every 63 band samples."""
    def pair(**kw):
        return [mr.render_cube(box, "cam", "lamp", mr.RenderSettings(spp=32, seed=s, illumination=False, **kw))
                for s in (1, 2)]

    bands, strat = pair(bands_per_path=64), pair(wavelengths="stratified")
    assert_same_within_noise(bands[0].cube, strat[0].cube)
    assert_same_within_noise(bands[1].cube, strat[1].cube)
    i = int(np.argmin(np.abs(box.spectral_grid.wavelengths - 550)))

    def band_noise(a, b):
        lit = a.cube[..., i] > 0.05 * a.cube[..., i].max()
        d = (a.cube[..., i] - b.cube[..., i])[lit] / np.sqrt(2)
        return d.std() / a.cube[..., i][lit].mean()

    assert band_noise(*bands) < band_noise(*strat) / 3, (band_noise(*bands), band_noise(*strat))
    assert bands[0].stats["nonfinite_samples"] == 0 and bands[0].stats["band_sets"] == 1
    assert bands[0].stats["paths_per_pixel"] == 32 and bands[0].stats["samples_per_band"] == 32


def test_bands_per_path_changes_the_noise_not_the_cube(box):
    one = mr.render_cube(box, "cam", "lamp", mr.RenderSettings(spp=32, seed=3, bands_per_path=64))
    four = mr.render_cube(box, "cam", "lamp", mr.RenderSettings(spp=32, seed=4, bands_per_path=16))
    assert one.stats["samples_per_band"] == 32 and four.stats["samples_per_band"] == 8
    assert one.stats["band_sets"] == 1 and four.stats["band_sets"] == 4
    # what multijitter renders of n asked: a ⌊√n⌋ × ⌈n/⌊√n⌋⌉ grid, so 32 -> 35 (one set), 8 -> 8 (four)
    assert one.stats["samples_per_band_rendered"] == 35 and one.stats["paths_per_pixel_rendered"] == 35
    assert four.stats["samples_per_band_rendered"] == 8 and four.stats["paths_per_pixel_rendered"] == 32
    assert one.stats["paths_per_pixel"] == 32  # what was asked, as before
    assert_same_within_noise(one.cube, four.cube)
    assert_same_within_noise(one.illumination, four.illumination)


@pytest.mark.parametrize("sampler, spp", [("ldsampler", 16), ("orthogonal", 36), ("independent", 8)])
def test_every_sampler_renders_the_same_cube(box, sampler, spp):
    ref = mr.render_cube(box, "cam", "bulb", mr.RenderSettings(spp=32, seed=5, illumination=False))
    other = mr.render_cube(box, "cam", "bulb", mr.RenderSettings(spp=spp, seed=6, sampler=sampler,
                                                                 illumination=False))
    assert other.renderer["settings"]["sampler"] == sampler
    assert_same_within_noise(other.cube, ref.cube)


def test_same_cube_whatever_the_thread_count(box):
    import drjit as dr

    settings = mr.RenderSettings(spp=16, seed=7)
    a = mr.render_cube(box, "cam", "lamp", settings)
    n = dr.thread_count()
    try:
        dr.set_thread_count(1)
        b = mr.render_cube(box, "cam", "lamp", settings)
    finally:
        dr.set_thread_count(n)
    assert np.array_equal(a.cube, b.cube) and np.array_equal(a.illumination, b.illumination)


def test_a_scene_of_many_shapes_loads_in_the_same_order_every_time():
    """Light sampling picks emitters by their order in the loaded scene: Mitsuba's ``optimize`` step
    merged shapes in an order that changed per load (a different cube per load); illumix loads
    without it, so the order, and the cube, are the same on every load."""
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene

    doc = box_scene()
    doc["shapes"] += [{"name": f"ball{i}", "type": "sphere", "material": "white", "center": (0.1 * i - 0.9, 0.1, 0.3),
                       "radius": 0.04} for i in range(24)]
    doc["shapes"] += [{"name": f"lamp{i}", "type": "sphere", "center": (0.15 * i - 0.6, 1.6, -0.5), "radius": 0.03,
                       "emitter": {"group": "lamp", "strength": 1.0 + i}} for i in range(8)]
    scene = scene_from_dict(doc)
    orders = {tuple(s.id() for s in load_mitsuba_scene(scene, "cam", ["lamp"])[0].shapes()) for _ in range(4)}
    assert len(orders) == 1
    st = mr.RenderSettings(spp=8, seed=3, illumination=False)
    a, b = (mr.render_cube(scene, "cam", "lamp", st) for _ in range(2))
    assert np.array_equal(a.cube, b.cube)


@pytest.mark.parametrize("kwargs, needle", [
    ({"sampler": "ldsampler", "spp": 48}, "a power of 2"),
    ({"sampler": "orthogonal", "spp": 49}, "a prime squared"),
    ({"spp": 30}, "multiple of 4"),
    ({"bands_per_path": 6}, "multiple of 4"),
    ({"adaptive": True}, "wavelengths 'stratified'"),
    ({"noise_target": 0.05}, "wavelengths 'stratified'"),
    ({"sampler": "sobol"}, "pixel sampler"),
])
def test_refusals(kwargs, needle):
    with pytest.raises(SceneError, match=needle):
        mr.RenderSettings(**kwargs)


def test_spp_rules():
    assert spp_allowed("ldsampler", 64) and not spp_allowed("ldsampler", 48)
    assert spp_allowed("orthogonal", 49) and not spp_allowed("orthogonal", 16) and not spp_allowed("orthogonal", 50)
    assert all(spp_allowed("multijitter", n) for n in (1, 7, 48))
