"""Adaptive sampling (renderer_jobs.adaptive_spp): the allocation itself (pure numpy) and, rendered,
that it keeps the estimate unbiased and spends the same number of paths."""

from __future__ import annotations

import numpy as np
import pytest

from illumix.renderer_jobs import adaptive_spp


def pilot_sums(v: np.ndarray, n: int = 16, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel pilot sums of Y and Y² over n paths whose relative variance per path is ``v``
    (mean 1 plus noise in the sums): what ``render_cube`` hands to the allocation."""
    rng = np.random.default_rng(seed)
    s1 = n * rng.uniform(0.9, 1.1, v.shape)
    s2 = s1 ** 2 / n * (1 + v)
    return s1, s2


def test_allocation_spends_the_budget_and_follows_sqrt_v():
    rng = np.random.default_rng(0)
    raw = rng.lognormal(0.0, 1.5, size=(30, 40))
    s1, s2 = pilot_sums(raw)
    n, v = adaptive_spp.allocate(s1, s2, 16, spp=64, pilot=16)
    assert n.shape == v.shape == raw.shape and n.dtype == np.int64
    assert np.array_equal(v, adaptive_spp.relative_variance(s1, s2, 16))
    assert abs(n.sum() / (64 * v.size) - 1) < 0.01 and n.min() >= 16 and n.max() <= 8 * 64
    extra = n - 16
    ratio = extra / np.sqrt(v)     # ∝ √v: within quarter-octave quantisation, rounding and S(x)
    ok = extra > 20
    assert np.percentile(ratio[ok], 95) / np.percentile(ratio[ok], 5) < 1.25
    on = np.zeros(v.shape, dtype=bool)
    on[5:20, 10:30] = True
    na, _ = adaptive_spp.allocate(s1, s2, np.where(on, 16, 0), 64, 16, active=on)
    assert np.all(na[~on] == 0) and na[on].min() >= 16 and abs(na.sum() / (64 * on.sum()) - 1) < 0.01


def test_allocation_does_not_depend_on_a_pixels_own_samples():
    """Changing only one pixel's pilot sums leaves that pixel's count unchanged (so its estimate
    stays unbiased), while its neighbours react."""
    s1, s2 = pilot_sums(np.random.default_rng(3).lognormal(0.0, 1.0, (12, 14)), seed=3)
    base, _ = adaptive_spp.allocate(s1, s2, 16, 64, 16, seed=4)
    for y, x in ((0, 0), (5, 6), (11, 3)):
        s1c, s2c = s1.copy(), s2.copy()
        s1c[y, x] *= 3
        s2c[y, x] *= 50
        n, _ = adaptive_spp.allocate(s1c, s2c, 16, 64, 16, seed=4)
        assert n[y, x] == base[y, x]
        assert not np.array_equal(n, base)


def test_allocation_degenerate_cases():
    z = np.zeros((4, 5))
    assert np.all(adaptive_spp.allocate(z, z, 16, 64, 16)[0] == 64)           # no light seen: uniform
    s1, s2 = pilot_sums(np.ones((4, 5)))
    assert np.all(adaptive_spp.allocate(s1, s2, 16, 16, 16)[0] == 16)        # no budget beyond the pilot
    s1, s2 = np.zeros((10, 10)), np.zeros((10, 10))
    s1[3, 3], s2[3, 3] = 16.0, 16.0 * 5                                        # one lit pixel: its 24
    n, v = adaptive_spp.allocate(s1, s2, 16, 32, 16)                          # neighbours share the rest
    assert np.all(n[v == 0] == 16) and (v > 0).sum() == 24 and n.max() <= 8 * 32
    assert abs(n.sum() / (32 * 100) - 1) < 0.03   # 24 of 100 pixels share it: x's pull on S is largest here


def test_allocation_is_invariant_to_a_tiny_rescaling_of_the_sums():
    """Relit renders (another emission) see the sums perturbed by float rounding: same allocation."""
    rng = np.random.default_rng(1)
    s1, s2 = pilot_sums(rng.lognormal(0.0, 1.0, size=(24, 32)), seed=1)
    a, _ = adaptive_spp.allocate(s1, s2, 16, 64, 16)
    k = 1 + 1e-7 * rng.standard_normal(s1.shape)
    b, _ = adaptive_spp.allocate(s1 * k, s2 * k * k, 16, 64, 16)
    assert np.array_equal(a, b)


def test_relative_variance_excludes_the_pixel_itself():
    """A pixel's own pilot does not change its v (so its sample count is independent of its samples)."""
    rng = np.random.default_rng(2)
    s1 = rng.uniform(1, 2, (9, 9)) * 16
    s2 = s1 ** 2 / 16 * rng.uniform(1.1, 2.0, (9, 9))
    v = adaptive_spp.relative_variance(s1, s2, 16)
    s1b, s2b = s1.copy(), s2.copy()
    s1b[4, 4] *= 10
    s2b[4, 4] *= 1000
    vb = adaptive_spp.relative_variance(s1b, s2b, 16)
    assert vb[4, 4] == pytest.approx(v[4, 4], rel=1e-12)
    assert not np.isclose(vb[4, 5], v[4, 5])  # its neighbours do see it
    for y, x in ((0, 0), (0, 4), (8, 8)):     # border and corner pixels too (no edge replication)
        s1c, s2c = s1.copy(), s2.copy()
        s1c[y, x] *= 10
        s2c[y, x] *= 1000
        assert adaptive_spp.relative_variance(s1c, s2c, 16)[y, x] == pytest.approx(v[y, x], rel=1e-12)
    assert adaptive_spp.relative_variance(s1[:1, :1], s2[:1, :1], 16)[0, 0] == 0  # 1×1: no neighbours
    assert np.all(adaptive_spp.relative_variance(np.zeros((3, 3)), np.zeros((3, 3)), 16) == 0)


@pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                    reason="rendering needs the optional extra illumix[render]")
def test_adaptive_render_is_unbiased_and_spends_the_same_paths():
    """Image means of adaptive and uniform renders agree within 5 standard errors (the error of a
    difference of means over independent pixels); the adaptive cube reports its per-pixel spp."""
    from illumix.scene import demo
    from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube

    room = demo.demo_room(0, resolution=(48, 36))
    a = render_cube(room, "front", "desk", RenderSettings(spp=64, seed=1, adaptive=True, wavelengths="stratified"))
    u = render_cube(room, "front", "desk", RenderSettings(spp=64, seed=2, adaptive=False, wavelengths="stratified"))
    sp = a.stats["spp_per_pixel"]
    assert sp["pilot"] == 16 and sp["min"] >= 16 and sp["max"] > 64 and "spp_per_pixel" not in u.stats
    assert a.renderer["settings"]["adaptive_spp"] is True
    d = (a.cube.sum(-1) - u.cube.sum(-1)).ravel()
    se = d.std() / np.sqrt(d.size)
    assert abs(d.mean()) < 5 * se
    # below twice the pilot there is nothing to distribute: uniform, bit for bit
    lo = render_cube(room, "front", "desk", RenderSettings(spp=24, seed=3, adaptive=True, wavelengths="stratified"))
    lo_u = render_cube(room, "front", "desk", RenderSettings(spp=24, seed=3, adaptive=False, wavelengths="stratified"))
    assert np.array_equal(lo.cube, lo_u.cube)


def test_to_target_gives_each_pixel_the_paths_its_variance_needs():
    v = np.array([[0.0, 1e-3, 0.5], [1.0, 4.0, 100.0]])
    n = adaptive_spp.to_target(v, 0.1, pilot=16, max_spp=1024)
    assert n.tolist() == [[16, 16, 50], [100, 400, 1024]]    # ⌈v/0.01⌉ within [pilot, max]
    pred = adaptive_spp.predicted_noise(v, n)
    assert np.all(pred[(n > 16) & (n < 1024)] <= 0.1 + 1e-12) and pred[1, 2] > 0.1 and pred[0, 0] == 0
    with pytest.raises(ValueError, match="noise target"):
        adaptive_spp.to_target(v, 1.5, 16, 64)


@pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                    reason="rendering needs the optional extra illumix[render]")
def test_noise_target_render_meets_its_target():
    """Two seeds per target: the measured relative noise of each pixel's band mean — (a − b)/√2 over
    the mean, RMS over the 1728 pixels, itself uncertain by ~2 % — lies within 0.6–1.25 × the target
    (the pilot's neighbourhood variance is an estimate from 384 paths: ±25 % covers its error; a
    miscalibrated rule such as v/target for v/target² lands at 1.6×), and halving the target costs
    ~4× the paths."""
    from illumix.scene import demo
    from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube

    room = demo.demo_room(0, resolution=(48, 36))
    mean_spp = {}
    for target in (0.2, 0.1):
        a, b = (render_cube(room, "front", "desk", RenderSettings(spp=1024, seed=s, noise_target=target, wavelengths="stratified"))
                for s in (1, 2))
        ya, yb = (r.cube.astype(np.float64).mean(-1) for r in (a, b))
        m = (ya + yb) / 2
        assert np.all(m > 0)
        rms = np.sqrt(np.mean(((ya - yb) / np.sqrt(2) / m) ** 2))
        assert 0.6 * target <= rms <= 1.25 * target, (target, rms)
        assert a.stats["noise_target"]["target"] == target and a.renderer["settings"]["noise_target"] == target
        mean_spp[target] = a.stats["spp_per_pixel"]["mean"]
    assert 3.0 <= mean_spp[0.1] / mean_spp[0.2] <= 5.0
