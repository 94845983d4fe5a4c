"""``IllumixDataset``'s raw item, normalised in one pass, against the rule written out in float64:
with noise DN → (DN − black)/(white − black); ``max`` then divides by the peak."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
from illumix_client.torch_dataset import IllumixDataset


class _Sample:
    def __init__(self, raw, meta):
        self.raw, self.meta = raw, meta


@pytest.mark.parametrize("norm", ["max", "exposure", "none"])
@pytest.mark.parametrize("noise", [None, {"black_level": 64, "bit_depth": 12}, {"white_level": 1023}])
@pytest.mark.parametrize("bayer", [False, True])
def test_raw_items_follow_the_normalisation_rule(norm, noise, bayer):
    rng = np.random.default_rng(0)
    raw = rng.random((5, 7) if bayer else (5, 7, 3), dtype=np.float32) * 900 + 64
    ds = IllumixDataset.__new__(IllumixDataset)  # only raw_norm matters here
    ds.raw_norm = norm
    out = ds._norm_raw(_Sample(raw, {"noise": noise}))
    ref = (raw[None] if bayer else raw.transpose(2, 0, 1)).astype(np.float64)
    if norm != "none" and noise:
        white = noise.get("white_level") or 2 ** noise["bit_depth"] - 1
        black = noise.get("black_level", 0)
        ref = (ref - black) / (white - black)
    if norm == "max":
        ref = ref / ref.max()
    assert out.dtype == np.float32 and out.flags.c_contiguous and out.shape == ref.shape
    np.testing.assert_allclose(out, ref, rtol=1e-6, atol=1e-7)


def test_an_all_dark_raw_stays_zero_not_nan():
    ds = IllumixDataset.__new__(IllumixDataset)
    ds.raw_norm = "max"
    out = ds._norm_raw(_Sample(np.zeros((4, 4, 3), np.float32), {}))
    assert np.all(out == 0)
