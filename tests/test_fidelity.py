"""The fidelity gate on a small held-out corpus: what /sample serves by default is never worse than
the plain render (issue 33; the whole corpus: ``python bench/fidelity.py``, bench/FIDELITY.md).

Two scenes the defaults were never chosen on, at 64×48, through the real job runner and the
service's composition: emitters seen in frame (the earlier denoiser averaged a lamp's pixels among
themselves: its group's frame sum rose by 105 %, its emitter pixels' error by 600×) and a spot
cone's rim (2.4 % of pixels biased beyond 3σ, against the test's own floor of 0.26 %). Renders are
deterministic (fixed seeds), so the figures are too; about 30 s.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    pytest.importorskip("mitsuba")
    sys.path.insert(0, str(BENCH))
    try:
        import fidelity
    finally:
        sys.path.remove(str(BENCH))
    return fidelity.main(["--quick", "--cache", str(tmp_path_factory.mktemp("fidelity"))])


def test_default_serving_moves_no_group_s_light(quick):
    """A linear filter that moves light between pixels changes a group's frame sum; the default
    may change it by at most 0.5 % (emitter pixels are left as rendered)."""
    assert quick["n_scenes"] == 2
    assert quick["max_mean_shift_pct"] <= 0.5, quick["scenes"]


def test_default_serving_is_not_biased_beyond_the_noise(quick):
    """At most 0.3 % of the served pixels (raw, illumination, illum, gain, mixture, sRGB) biased
    beyond 3σ of the render's own noise — or the test's own floor (the plain render under the same
    test) + 0.1 point, should the renderer's noise ever lift that floor."""
    floor = quick["biased_pixel_pct_plain"]
    assert quick["biased_pixel_pct"] <= max(0.3, floor + 0.1), quick["biased_pixel_pct_by_output"]


def test_no_pixel_class_is_served_worse_than_rendered(quick):
    """Emitter, edge, flat (and glossy, glass where present): the default's error against the
    reference is nowhere above the plain render's."""
    assert quick["denoised_worse_pct"] == 0, quick["denoised_worse"]
    classes = {c for s in quick["scenes"] for c in s["classes"]}
    assert {"emitter", "edge", "flat"} <= classes
