"""The dtype policy (store.codec): exponent-scaled float16 with a float32 fallback.

Bound under test: a value held in float16 round-trips with |x̂ − x| ≤ 2⁻¹¹·|x|. Why: the two scales
are powers of two (exact in float32), so the only rounding is float32 → float16 round-to-nearest,
whose error is at most half an ULP of an 11-bit significand, i.e. 2⁻¹¹ of the value, for every
scaled value in float16's normal range — which the policy guarantees or else falls back to float32.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as hs
from hypothesis.extra import numpy as hnp
from store_testutil import NB, add_view, cube, meta, new_store

from illumix.store.codec import REL_BOUND_F16, decode, encode


def _rel(a: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.abs(a.astype(np.float64) - ref) / np.where(ref == 0, 1, np.abs(ref))


def _highlight_and_shadows() -> np.ndarray:
    c = cube(48, 80, seed=5)
    rng = np.random.default_rng(5)
    c[:12, :20] = 1e-7 * (1 + 0.1 * rng.random((12, 20, NB), dtype=np.float32))  # deep shadow, noisy
    c[-2:, -3:] = 1e6                                                                 # visible emitter
    return c


def test_naive_float16_cannot_hold_it():
    c = _highlight_and_shadows()
    with np.errstate(over="ignore"):
        naive = c.astype(np.float16).astype(np.float32)
    assert np.isinf(naive[-2:, -3:]).all()                          # the 1e6 emitter overflows 65504
    assert _rel(naive[:12, :20], c[:12, :20]).max() > 0.01          # shadows are float16 subnormals


def test_highlight_1e6_and_shadows_1e7_round_trip_in_float16(tmp_path):
    st = new_store(tmp_path / "st")
    add_view(st)
    c = _highlight_and_shadows()
    m = st.write_cube("s", "v", "g", c, meta())
    assert m.storage.dtype == "float16" and m.storage.underflow_values == 0
    assert m.storage.rel_error_bound == REL_BOUND_F16 == 2.0**-11
    got = st.read_cube("s", "v", "g")
    assert np.isfinite(got).all()
    assert _rel(got, c).max() <= REL_BOUND_F16
    assert 1e6 * (1 - REL_BOUND_F16) <= got[-1, -1, 0] <= 1e6 * (1 + REL_BOUND_F16)
    f32 = new_store(tmp_path / "f32", dtype_policy="float32")
    add_view(f32)
    m32 = f32.write_cube("s", "v", "g", c, meta())
    assert m.storage.nbytes_stored < 0.6 * m32.storage.nbytes_stored  # float16 really halves it


def test_pixel_spectrum_beyond_29_stops_falls_back_to_exact_float32(tmp_path):
    st = new_store(tmp_path / "st")
    add_view(st)
    c = cube(seed=2)
    c[0, 0, 0], c[0, 0, 1] = 1e6, 1e-9 * c[..., 1].max()  # one pixel spans ~2^50 between two bands
    m = st.write_cube("s", "v", "g", c, meta())
    assert m.storage.dtype == "float32" and "2^29" in m.storage.reason and m.storage.rel_error_bound == 0
    assert np.array_equal(st.read_cube("s", "v", "g"), c)


def test_forced_float16_never_inf_or_nan_and_keeps_its_absolute_bound():
    c = cube(seed=2)
    c[0, 0, 0], c[0, 0, 1] = 1e6, 1e-9 * c[..., 1].max()
    enc = encode(c, "float16")
    assert enc.dtype == "float16" and enc.underflow >= 1
    d = decode(enc.data, enc.exponent, enc.band_exponent)
    assert np.isfinite(d).all()
    beta = np.asarray(enc.band_exponent)
    n = np.abs(c) * np.ldexp(1.0, -beta)                       # band-normalised values
    # absolute bound of values below float16's normal range: 2^-25 * 2^(ε-15) * 2^β ≤ 2^-39 max_b n * 2^β
    absb = 2.0**-39 * n.max(axis=-1, keepdims=True) * np.ldexp(1.0, beta)
    err = np.abs(d.astype(np.float64) - c)
    assert np.all(err <= REL_BOUND_F16 * np.abs(c) + absb)
    assert _rel(d[1:], c[1:]).max() <= REL_BOUND_F16         # every other pixel keeps the relative bound


def test_zeros_negatives_and_forced_float32_are_exact_or_bounded():
    c = cube(seed=3)
    c[5:9, 5:9] = 0.0
    c[10, 10, :] *= -1
    c[11, 11, 3] = 0.0
    enc = encode(c)
    d = decode(enc.data, enc.exponent, enc.band_exponent)
    assert enc.dtype == "float16" and (d[5:9, 5:9] == 0).all() and d[11, 11, 3] == 0
    assert (np.sign(d) == np.sign(c)).all() and _rel(d, c).max() <= REL_BOUND_F16
    e32 = encode(c, "float32")
    assert e32.dtype == "float32" and np.array_equal(decode(e32.data, None, None), c)


def test_render_like_cube_stays_float16():
    """The policy must keep float16 for realistic renders (else it would not halve the store)."""
    enc = encode(cube(96, 128, seed=11))
    assert enc.dtype == "float16" and enc.underflow == 0


@settings(max_examples=60, deadline=None)
@given(logmag=hnp.arrays(np.float64, (3, 4, 8), elements=hs.floats(-12, 12)),
       pix=hnp.arrays(np.float64, (3, 4, 1), elements=hs.floats(-20, 20)),
       sign=hnp.arrays(np.int8, (3, 4, 8), elements=hs.sampled_from([-1, 0, 1])))
def test_policy_property_bound_or_exact(logmag, pix, sign):
    """Any finite cube: decode is finite and within 2^-11 (float16) or exact (float32 fallback)."""
    c = (sign * 10.0 ** (logmag + pix)).astype(np.float32)
    enc = encode(c)
    d = decode(enc.data, enc.exponent, enc.band_exponent)
    assert np.isfinite(d).all() and (d[c == 0] == 0).all()
    if enc.dtype == "float16":
        assert _rel(d, c).max() <= REL_BOUND_F16
    else:
        assert np.array_equal(d, c)
