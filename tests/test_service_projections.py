"""Cached whole-frame projections (engine.projections): a crop sliced from a frame's projection is
the sample projected from the cube, for every request that may hit it, and never for another.

The reference is the same service with projections off (``projection_mb=0``): the two paths differ
only in where the intensity multiplies (after the float32 band sum, or inside it), so they agree to
float32 rounding (rtol 1e-6, the order of 63 float32 additions' relative error).
"""

from __future__ import annotations

import numpy as np
import pytest
import synthetic_store as synth

from illumix.service.app import create_app
from illumix.engine.sampling import build_sample
from illumix.engine.spec import SampleSpec
from illumix.store import CubeStore

V0 = {"scene": "synth", "view": "v0"}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("proj") / "store"
    synth.build(path, illumination=True)
    return CubeStore.open(str(path), mode="r")


def ctx_of(store, projection_mb):
    return create_app(store, cache_mb=64, projection_mb=projection_mb).state.ctx


def sample(ctx, **kw):
    arrays, _ = build_sample(SampleSpec(**(V0 | kw)), ctx)
    return arrays


REQUESTS = [
    dict(sensor="XYZ", pair="A,D65", crop="8,4,32,24", outputs="raw,gain,mask"),
    dict(sensor="XYZ", pair="A,D65", crop="8,4,32,24", intensities="0.3,2", outputs="raw,gain,illum,mixture"),
    dict(sensor="XYZ", pair="D65,A", crop="8,4,32,24", outputs="raw,gain"),  # swapped: other keys
    dict(sensor="Nikon 5100 (NPL)", pair="A,D65", crop="0,0,64,48", outputs="raw,gain,srgb,weights"),
    dict(sensor="XYZ", pair="FL11,D50", crop="16,8,16,16", size="8x8", gt="formula", outputs="raw,gain"),
]


def test_projected_samples_equal_the_cube_path(store):
    on, off = ctx_of(store, 16), ctx_of(store, 0)
    assert off.projections is None
    for _ in range(3):  # the second request of a key projects the frame, the third slices it
        for req in REQUESTS:
            a, b = sample(on, **req), sample(off, **req)
            assert a.keys() == b.keys()
            for k in a:
                np.testing.assert_allclose(a[k], b[k], rtol=1e-6, atol=1e-12, err_msg=f"{req} {k}")
    assert on.projections.hits > 0 and on.projections.misses > 0


def test_a_key_is_projected_on_its_second_request_and_sliced_after(store):
    ctx = ctx_of(store, 16)
    req = dict(sensor="XYZ", pair="A,D65", crop="0,0,16,16", outputs="raw,gain", gt="formula")
    sample(ctx, **req)
    assert (ctx.projections.hits, ctx.projections.misses) == (0, 0)  # one crop: projected from the cube
    sample(ctx, **req)
    assert ctx.projections.misses == 2  # both groups' frames projected and kept
    hits, misses = ctx.cache.hits, ctx.cache.misses
    sample(ctx, **(req | {"crop": "20,10,16,16", "intensities": "0.5,1"}))
    assert ctx.projections.hits == 2
    # no cube was touched: the only cache reads are the view's mask and emitter AOVs
    assert (ctx.cache.hits - hits, ctx.cache.misses - misses) == (2, 0)


def test_whole_frames_are_kept_at_once_and_spectral_outputs_read_the_cubes(store):
    ctx = ctx_of(store, 16)
    sample(ctx, sensor="XYZ", pair="A,D65", outputs="raw,gain")
    assert ctx.projections.misses == 4  # transport and illumination cubes (physical ground truth)
    sample(ctx, sensor="XYZ", pair="A,D65", crop="0,0,8,8", outputs="raw,reflectance")
    assert ctx.projections.hits == 0  # the reflectance needs the bands: no projection used


def test_the_cache_bound_holds(store):
    ctx = ctx_of(store, 1)  # 1 MiB: 48x64x3 float32 frames are 36 KiB each
    for ill in ("A", "D65", "FL11", "D50", "FL2", "D75"):
        for _ in range(2):
            sample(ctx, sensor="XYZ", pair=f"{ill},D65", outputs="raw")
    assert ctx.projections.cache.total_cost <= ctx.projections.cache.max_cost


def test_warmed_projections_serve_the_first_crop(store):
    from illumix.engine.warm import warm_cache, warm_projections

    ctx = ctx_of(store, 16)
    assert warm_projections(ctx, ["XYZ"], ["A"])["projections"] == 0  # only cubes already decoded
    warm_cache(ctx)
    got = warm_projections(ctx, ["XYZ"], ["A", "D65"])
    # synth/v0: 2 groups × 2 illuminants × (transport + illumination); the other views have one
    # flat group, or a cut emission that D65 cannot relight (skipped)
    assert got["projections"] >= 8 and ctx.projections.misses == 0
    sample(ctx, sensor="XYZ", pair="D65,A", crop="3,5,16,16", outputs="raw,gain")
    assert ctx.projections.hits == 4 and ctx.projections.misses == 0


def test_admission_keeps_popular_frames_from_keys_used_once():
    """TinyLFU's rule: a key used once does not evict a frame asked for more often."""
    from illumix.engine.projections import ProjectionCache

    cube = np.ones((8, 8, 4), np.float32)
    w = np.ones((4, 3))
    frame = 8 * 8 * 3 * 4
    pc = ProjectionCache(2 * frame)  # room for two frames
    for _ in range(3):
        for hot in ("a", "b"):
            assert pc.window(hot, lambda: cube, w, (0, 0, 8, 8), frame, whole_frame=True) is not None
    for i in range(50):  # a stream of keys seen once or twice (a continuous CCT range)
        for _ in range(2):
            pc.window(f"cold{i}", lambda: cube, w, (0, 0, 8, 8), frame, whole_frame=False)
    assert "a" in pc.cache and "b" in pc.cache
    hits = pc.hits
    pc.window("a", lambda: cube, w, (0, 0, 4, 4), frame, whole_frame=False)
    assert pc.hits == hits + 1

