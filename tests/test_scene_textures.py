"""Spectral textures: a label map mixing measured spectra renders each texel's band values exactly
(closed form under a distant light), patterns are deterministic in their seed, and bad textures
fail with one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from illumix.scene.load import scene_from_dict
from illumix.scene.schema import SceneError
from illumix.scene.textures import PATTERNS, PatternTexture

SPECTRA = [{"library": "ColorChecker N Ohta", "index": 14}, {"library": "ColorChecker N Ohta", "index": 2}]


def _doc(reflectance) -> dict:
    return {"name": "tex", "materials": {"m": {"kind": "diffuse", "reflectance": reflectance, "two_sided": False}},
            "shapes": [{"name": "r", "type": "rectangle", "material": "m"}],
            "lights": [{"name": "sun", "type": "directional", "group": "g", "direction": [0, 0, -1], "strength": 1.0}],
            "views": [{"name": "v", "origin": [0, 0, 4], "target": [0, 0, 0], "fov": 28.0725, "resolution": [32, 32]}]}


@pytest.mark.parametrize("pattern", PATTERNS)
def test_patterns_are_deterministic_and_in_range(pattern):
    t = PatternTexture(pattern=pattern, spectra=SPECTRA + [{"value": 0.5}], seed=3, resolution=64)
    a, b = t.label_map(), PatternTexture(pattern=pattern, spectra=SPECTRA + [{"value": 0.5}], seed=3,
                                         resolution=64).label_map()
    assert a.shape == (64, 64) and a.dtype == np.float32
    assert np.array_equal(a, b)
    assert a.min() >= 0 and a.max() <= 2
    assert len(np.unique(a)) > 1


def test_checker_texture_renders_each_texel_exactly():
    """A 2×2 checker of two ColorChecker patches under a unit distant light along the normal: each
    cell's band values are ρ_b/π exactly (band-constant spectra, exact band integration)."""
    pytest.importorskip("mitsuba")
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    scene = scene_from_dict(_doc({"pattern": "checker", "spectra": SPECTRA, "params": {"cells": 2}}))
    cube = render_cube(scene, "v", "g", RenderSettings(spp=16)).cube
    tex = scene.materials["m"].reflectance
    rho, labels = scene.texture_spectra(tex, "m"), tex.label_map()
    # the camera frames [-1, 1]² exactly (fov 2·atan(1/4)): quadrant centres at pixels 8 and 24; the
    # map's row 0 is v = 0, the rectangle's bottom edge (as Mitsuba's bitmaps)
    for (py, px), (ly, lx) in (((8, 8), (-1, 0)), ((8, 24), (-1, -1)), ((24, 24), (0, -1)), ((24, 8), (0, 0))):
        assert np.allclose(cube[py, px] * math.pi, rho[int(labels[ly, lx])], rtol=1e-4), (py, px)
    assert labels[0, 0] != labels[-1, 0]  # the checker differs between the quadrants compared


def test_bad_textures_fail_with_one_line():
    with pytest.raises(SceneError, match="pattern 'tiles' has no parameter"):
        scene_from_dict(_doc({"pattern": "tiles", "spectra": SPECTRA, "params": {"rings": 3}}))
    with pytest.raises(SceneError, match="does not exist"):  # not an image: a spectrum CSV
        scene_from_dict(_doc({"file": "x.tif"}))
    with pytest.raises(SceneError, match="does not exist"):
        scene_from_dict(_doc({"file": "missing.png"}))
    with pytest.raises(SceneError, match="index 99 out of range"):
        scene_from_dict(_doc({"pattern": "wood", "spectra": [SPECTRA[0], {"library": "ColorChecker N Ohta",
                                                                           "index": 99}]}))


def test_cycles_backend_refuses_textures():
    from illumix.renderer_jobs.cycles.job import material_doc

    scene = scene_from_dict(_doc({"pattern": "checker", "spectra": SPECTRA}))
    with pytest.raises(SceneError, match="Mitsuba backend only"):
        material_doc(scene, "m", lambda msg: None)
