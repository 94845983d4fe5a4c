"""Kernels are reused across scenes (issue 38): Dr.Jit's instance registry padded to fixed sizes.

A symbolic call's offset table has one entry per registry ID of its class, so scenes with other
numbers of shapes compiled kernels that differed only in those offsets;
:mod:`renderer_jobs.mitsuba.instance_padding` pads the ID bounds to half-octave buckets. Checked
here with Dr.Jit's kernel history: a second scene with one more shape (same bucket) compiles
nothing, while without the padding it does; padding changes no pixel.
"""

from __future__ import annotations

import numpy as np
import pytest
from illumix.renderer_jobs.mitsuba import instance_padding as ip
from illumix.renderer_jobs.mitsuba.scene_dict import load_padded
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba


def test_buckets_are_half_octaves():
    sizes = [ip.bucket(n) for n in range(3000)]
    assert sizes[:17] == [16] * 17 and ip.bucket(17) == 24 and ip.bucket(25) == 32 and ip.bucket(33) == 48
    assert all(b >= n for n, b in enumerate(sizes))
    assert all(b <= max(16, 1.5 * n) for n, b in enumerate(sizes))  # never more than half again
    assert len(set(sizes)) <= 2 * np.log2(3000) + 1  # few layouts: logarithmic in the scene's size


def _scene(mi, balls: int) -> dict:
    doc = {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
           "sensor": {"type": "perspective", "fov": 45,
                      "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                      "film": {"type": "hdrfilm", "width": 16, "height": 12, "rfilter": {"type": "box"}},
                      "sampler": {"type": "independent", "sample_count": 4}},
           # every ball the same grey: a Mitsuba `uniform` value is a literal in its BSDF's code
           "light": {"type": "point", "position": [0, 2, 3], "intensity": {"type": "uniform", "value": 10.0}},
           "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"},
                     "to_world": mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(3)}}
    for k in range(balls):
        doc[f"ball{k}"] = {"type": "sphere", "center": [0.6 * k - 1, 0, 0], "radius": 0.25,
                           "bsdf": {"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.4}}}
    return doc


def _render(mi, dr, doc) -> tuple[np.ndarray, int, dict]:
    """The image, how many kernels the render had to build or load from disk (not in memory), and the
    registry's bounds while the scene was alive."""
    dr.kernel_history()  # read and cleared: only this render's kernels below
    scene = load_padded(mi, doc)
    img = np.array(mi.render(scene, spp=4, seed=1))
    jit = [e for e in dr.kernel_history() if str(e.get("type")).endswith("JIT")]
    return img, sum(1 for e in jit if not e.get("cache_hit") or e.get("cache_disk")), ip.id_bounds(mi)


@pytest.fixture
def history():
    mi, _ = import_mitsuba()
    if not mi.variant().startswith(("llvm_", "cuda_")) or not ip.id_bounds(mi):
        pytest.skip("no JIT variant or no registry query here: nothing is padded")
    import drjit as dr
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    yield mi, dr
    dr.set_flag(dr.JitFlag.KernelHistory, False)
    dr.kernel_history()
    ip.release_padding()


def test_a_scene_with_one_more_shape_builds_no_kernel(history, monkeypatch):
    mi, dr = history
    _render(mi, dr, _scene(mi, 2))  # this process's kernels for the bucket (floor + 2 balls: 3 shapes → 16)
    img, built, bounds = _render(mi, dr, _scene(mi, 6))  # 7 shapes: the same bucket, other data
    assert built == 0, f"{built} kernels built for a scene with more shapes"
    assert bounds["Shape"] == 16 and all(b == ip.bucket(b) for b in bounds.values()), bounds

    monkeypatch.setattr(ip, "ENABLED", False)  # the same pair unpadded: the layouts differ
    _render(mi, dr, _scene(mi, 2))
    plain, built, _ = _render(mi, dr, _scene(mi, 6))
    assert built > 0, "without padding the larger scene should need its own kernels (the test would show nothing)"
    np.testing.assert_array_equal(img, plain)  # inert instances are never hit: the same pixels


def test_padding_follows_the_scene_size(history):
    mi, _ = history
    big = load_padded(mi, _scene(mi, 20))  # 21 shapes, 21 BSDFs (+ the padding's own), 1 emitter
    bounds = ip.id_bounds(mi)
    assert all(b == ip.bucket(b) for b in bounds.values()), bounds
    assert bounds["Shape"] == 24 and bounds["Emitter"] == 16
    del big
    load_padded(mi, _scene(mi, 1))  # a smaller scene takes the freed IDs: back to the small layout
    assert ip.id_bounds(mi)["Shape"] == 16


def test_shapes_share_one_bsdf_per_material():
    """build_scene_dict hands Mitsuba one BSDF per material, not one per shape: the BSDF count (so the
    layout) follows the materials, and every call records fewer instances."""
    from illumix.renderer_jobs.mitsuba.scene_dict import build_scene_dict
    from illumix.scene.demo import demo_room
    scene = demo_room(0, (32, 24))
    doc = build_scene_dict(scene, scene.views[0].name, None)
    shapes = {k: v for k, v in doc.items() if k.startswith("shape_")}
    bsdfs = {k: v for k, v in doc.items() if k.startswith("bsdf")}
    assert all(v["bsdf"]["type"] == "ref" and v["bsdf"]["id"] in bsdfs for v in shapes.values())
    used = {s.material or "" for s in scene.shapes if s.name in {k[len("shape_"):] for k in shapes}}
    assert len(bsdfs) == len(used) < len(shapes)
