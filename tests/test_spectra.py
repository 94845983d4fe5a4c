"""Spectral libraries (issue 2, item 3): illuminants, sensors, reflectances and the file readers.

References are computed independently from colour-science's own tabulated data (see
``tests/independent.py``): band averages by a fine trapezoid rule, true integrals of products,
Planck's law by ``scipy.integrate.quad``.
"""

from __future__ import annotations

import json

import colour
import numpy as np
import pytest
from scipy import integrate

from independent import band_average_fine, fine_lattice, integral_fine, interp, product_bound
from illumix.retarget import illuminants as ill
from illumix.retarget import reflectances as refl
from illumix.retarget import sensors as sen
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid
from illumix.retarget.groundtruth import white_point
from illumix.retarget.tables import read_csv_table, read_rawtoaces_camera

X = fine_lattice()
CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
D810 = "rawtoaces-data/data/camera/Nikon_D810_380_780_5.json"


def _cmfs_fine() -> np.ndarray:
    return interp(CMFS.wavelengths, CMFS.values, X)


def _colour_sd(name: str) -> colour.SpectralDistribution:
    kind, _, arg = name.partition(":")
    if kind == "blackbody":
        return colour.sd_blackbody(float(arg), colour.SpectralShape(300, 830, 1))
    return colour.SDS_ILLUMINANTS[name]


def _load_rawtoaces(path) -> tuple[np.ndarray, np.ndarray]:
    doc = json.loads(path.read_text())
    table = doc["spectral_data"]["data"]["main"]
    order = [doc["spectral_data"]["index"]["main"].index(c) for c in "RGB"]
    wl = np.array([float(k) for k in table])
    return wl, np.array([table[k] for k in table], dtype=float)[:, order]


# ================================================================================ illuminants

ILLUMINANTS = ["A", "D65", "D50", "FL2", "FL3.1", "FL11", "HP1", "LED-B1", "LED-V1", "blackbody:2856"]


@pytest.mark.parametrize("name", ILLUMINANTS)
def test_xyz_white_point_matches_colour_science_spectral_integration(name):
    sd = _colour_sd(name)
    phi = interp(sd.wavelengths, sd.values, X)
    cmf = _cmfs_fine()
    wp = white_point(sen.get_sensor("XYZ").weights(), ill.illuminant_spd(name))

    # (1) Same quantity, different algorithm: Σ_i x̄_i Φ̄_i Δλ with band averages from the fine
    #     trapezoid rule (exact for the interpolants): agreement to float rounding.
    band = band_average_fine(phi) @ band_average_fine(cmf)
    np.testing.assert_allclose(wp, band / band[1], rtol=1e-9)

    # (2) Against the true integral ∫ x̄ Φ dλ over the grid's span. Band-averaging each factor
    #     before multiplying errs per band by cov_band(x̄, Φ), bounded by sd(x̄)·sd(Φ): the bound
    #     B_k is computed from the data (≈0.03 % for A, up to 1 % for a line spectrum's z̄).
    #     With raw = c·(true + e), |e_k| ≤ B_k, the ratio error is ≤ (B_k + wp_k·B_G)/(true_G − B_G).
    true = integral_fine(phi[:, None] * cmf)
    bound = product_bound(phi, cmf)
    ref = true / true[1]
    tol = (bound + ref * bound[1]) / (true[1] - bound[1])
    assert np.all(np.abs(wp - ref) <= tol), (wp, ref, tol)
    assert wp[1] == 1.0


def test_white_point_of_a_real_camera_matches_independent_integration(shared_data):
    wl, rgb = _load_rawtoaces(shared_data / D810)
    cam = interp(wl, rgb, X)
    for name in ("A", "D65", "FL11"):
        sd = colour.SDS_ILLUMINANTS[name]
        phi = interp(sd.wavelengths, sd.values, X)
        wp = white_point(sen.get_sensor(str(shared_data / D810)).weights(), ill.illuminant_spd(name))
        band = band_average_fine(phi) @ band_average_fine(cam)
        np.testing.assert_allclose(wp, band / band[1], rtol=1e-9)
        true = integral_fine(phi[:, None] * cam)
        bound = product_bound(phi, cam)
        ref = true / true[1]
        assert np.all(np.abs(wp - ref) <= (bound + ref * bound[1]) / (true[1] - bound[1]))
    # Plausibility of the physics, not just the arithmetic: tungsten A is red-rich, blue-poor.
    wp_a = white_point(sen.get_sensor(str(shared_data / D810)).weights(), ill.illuminant_spd("A"))
    wp_d65 = white_point(sen.get_sensor(str(shared_data / D810)).weights(), ill.illuminant_spd("D65"))
    assert wp_a[0] > wp_d65[0] and wp_a[2] < wp_d65[2]


@pytest.mark.parametrize("name", ["A", "D65", "FL11", "LED-RGB1", "blackbody:3000", "daylight:5500"])
def test_illuminants_are_normalised_to_equal_energy_luminance(name):
    # Module docstring: Σ Φ̄ ȳ Δλ = Σ 1·ȳ Δλ. ȳ band averages computed independently.
    ybar = band_average_fine(interp(CMFS.wavelengths, CMFS.values[:, 1], X))
    spd = ill.illuminant_spd(name)
    assert spd @ ybar == pytest.approx(ybar.sum(), rel=1e-9)
    assert spd.shape == (63,) and spd.dtype == np.float64 and np.all(spd >= 0)


@pytest.mark.parametrize("kelvin", [1000.0, 2856.0, 6500.0, 20000.0])
def test_blackbody_shape_matches_planck_law(kelvin):
    c1, c2 = 3.741771852e-16, 1.438776877e-2  # 2πhc² [W m²] and hc/k [m K] (CODATA 2018)

    def planck(nm):
        lam = nm * 1e-9
        return c1 / lam**5 / np.expm1(c2 / (lam * kelvin))

    edges = DEFAULT_GRID.edges
    exact = np.array([integrate.quad(planck, a, b, epsrel=1e-12)[0] / (b - a)
                      for a, b in zip(edges[:-1], edges[1:])])
    spd = ill.illuminant_spd(f"blackbody:{kelvin:g}")
    ratio = spd / exact
    # The library interpolates Planck linearly between 1 nm samples: per-band relative error
    # ≈ (h²/12)·|f''/f| with h = 1 nm; |f''/f| < 2e-3 nm⁻² for T ≥ 1000 K on 392–708 nm, so < 2e-4.
    np.testing.assert_allclose(ratio / ratio.mean(), 1.0, rtol=2e-4)


@pytest.mark.parametrize("kelvin, table", [("6500", "D65"), ("5000", "D50"), ("7500", "D75")])
def test_daylight_parametric_reproduces_the_cie_d_tables(kelvin, table):
    # D65 etc. are nominal CCTs on the old c2 = 1.4380e-2 scale (D65 is 6504 K today); the
    # library converts. The tabulated D65 values are rounded to 4–5 significant digits, so
    # agreement to 5e-5 relative is what the tables allow.
    np.testing.assert_allclose(ill.illuminant_spd(f"daylight:{kelvin}"), ill.illuminant_spd(table),
                               rtol=5e-5)
    np.testing.assert_allclose(ill.illuminant_spd(f"daylight:{kelvin}K"),
                               ill.illuminant_spd(f"daylight:{kelvin}"), rtol=0)


@pytest.mark.parametrize("name, message", [
    ("blackbody:100", "outside 500-50000 K"),
    ("daylight:3000", "outside 4000-25000 K"),
    ("blackbody:warm", "must be a number in kelvin"),
    ("daylight:", "must be a number"),
])
def test_parametric_illuminants_refuse_bad_temperatures(name, message):
    with pytest.raises(SpectralError, match=message):
        ill.illuminant_spd(name)


def test_every_tabulated_illuminant_resolves_or_is_refused_for_coverage_only():
    lo, hi = DEFAULT_GRID.span
    resolved = 0
    for name in ill.builtin_names():
        sd = colour.SDS_ILLUMINANTS[name]
        covers = sd.wavelengths[0] <= lo and sd.wavelengths[-1] >= hi
        if covers:
            spd = ill.illuminant_spd(name)
            assert spd.shape == (63,) and np.all(np.isfinite(spd)) and np.all(spd >= 0), name
            resolved += 1
        else:
            with pytest.raises(SpectralError, match="samples cover"):
                ill.illuminant_spd(name)
    assert resolved >= 50  # A, D50-D75, FL1-FL12, FL3.1-15, HP1-5, LED-* at least


def test_illuminant_from_csv_file_equals_the_builtin_samples(tmp_path):
    sd = colour.SDS_ILLUMINANTS["FL11"]
    f = tmp_path / "my_lamp.csv"
    rows = "\n".join(f"{w:g},{v!r}" for w, v in zip(sd.wavelengths, sd.values))
    f.write_text("wavelength,value\n" + rows + "\n")
    np.testing.assert_allclose(ill.illuminant_spd(str(f)), ill.illuminant_spd("FL11"), rtol=1e-12)
    # an uploaded (registered) SPD by name
    extra = {"lamp": (sd.wavelengths, sd.values * 7.0)}  # scale is normalised away
    np.testing.assert_allclose(ill.illuminant_spd("lamp", extra=extra), ill.illuminant_spd("FL11"),
                               rtol=1e-12)


@pytest.mark.parametrize("content, message", [
    ("wavelength,value\n380,1\n500,-0.5\n780,1\n", "negative power at 500 nm"),
    ("wavelength,value\n400,1\n700,1\n", "samples cover 400-700 nm"),
    ("wavelength,value\n380,0\n780,0\n", "no luminance"),
    ("wavelength,a,b\n380,1,2\n780,1,2\n", "expected 1 value column"),
])
def test_bad_illuminant_files_are_refused(tmp_path, content, message):
    f = tmp_path / "bad.csv"
    f.write_text(content)
    with pytest.raises(SpectralError, match=message):
        ill.illuminant_spd(str(f))


@pytest.mark.parametrize("name, suggestion", [("D6", "'D65'"), ("FL13", "'FL1"), ("LED-B", "'LED-B")])
def test_unknown_illuminant_names_get_close_match_suggestions(name, suggestion):
    with pytest.raises(SpectralError, match=f"unknown illuminant.*did you mean.*{suggestion}"):
        ill.illuminant_spd(name)


def test_tabulated_illuminant_names_are_case_insensitive():
    # colour-science's SDS_ILLUMINANTS is a case-insensitive (canonical) mapping.
    np.testing.assert_array_equal(ill.illuminant_spd("fl11"), ill.illuminant_spd("FL11"))


def test_illuminant_on_another_grid():
    g = SpectralGrid(400, 700, 10)
    spd = ill.illuminant_spd("D65", g)
    sd = colour.SDS_ILLUMINANTS["D65"]
    ref = band_average_fine(interp(sd.wavelengths, sd.values, fine_lattice(400, 700, 10)), 10)
    np.testing.assert_allclose(spd / spd.mean(), ref / ref.mean(), rtol=1e-9)


# ================================================================================== sensors


def test_xyz_sensor_is_the_cie_1931_observer_peak_normalised():
    s = sen.get_sensor("XYZ")
    ref = band_average_fine(_cmfs_fine())
    assert s.sensitivities.shape == (63, 3)
    assert s.sensitivities.max() == 1.0
    # one common scale for all channels (ratios between channels are the colour)
    np.testing.assert_allclose(s.sensitivities, ref / ref.max(), rtol=1e-9)
    np.testing.assert_allclose(s.weights(), s.sensitivities * 5.0, rtol=0)


def test_rawtoaces_camera_file_is_read_and_band_averaged(shared_data):
    path = shared_data / D810
    wl, rgb = _load_rawtoaces(path)
    s = sen.get_sensor(str(path))
    assert s.name == "Nikon_D810"  # the _380_780_5 range suffix is dropped
    ref = band_average_fine(interp(wl, rgb, X))
    np.testing.assert_allclose(s.sensitivities, ref / ref.max(), rtol=1e-9, atol=1e-15)


def test_rawtoaces_channel_index_is_honoured(shared_data, tmp_path):
    doc = json.loads((shared_data / D810).read_text())
    table = doc["spectral_data"]["data"]["main"]
    doc["spectral_data"]["index"]["main"] = ["B", "G", "R"]
    doc["spectral_data"]["data"]["main"] = {k: [v[2], v[1], v[0]] for k, v in table.items()}
    f = tmp_path / "swapped.json"
    f.write_text(json.dumps(doc))
    a = sen.get_sensor(str(shared_data / D810)).sensitivities
    b = sen.get_sensor(str(f)).sensitivities
    np.testing.assert_array_equal(a, b)


def test_csv_camera_file_from_isetcam(shared_data):
    path = shared_data / "isetcam-spectra/csv/sensor__colorfilters__nikon__NikonD70.csv"
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    s = sen.get_sensor(str(path))
    ref = band_average_fine(interp(raw[:, 0], raw[:, 1:], X))
    np.testing.assert_allclose(s.sensitivities, ref / ref.max(), rtol=1e-9, atol=1e-15)


def test_sensor_folder_lookup_by_stem_with_suggestions(shared_data, monkeypatch):
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(shared_data / "rawtoaces-data/data/camera"))
    assert "Nikon_D810" in sen.builtin_names()
    by_name = sen.get_sensor("Nikon_D810")
    np.testing.assert_array_equal(by_name.sensitivities,
                                  sen.get_sensor(str(shared_data / D810)).sensitivities)
    with pytest.raises(SpectralError, match="unknown sensor 'Nikon_D81'.*did you mean.*'Nikon_D810'"):
        sen.get_sensor("Nikon_D81")


def test_colour_science_camera_that_does_not_cover_the_grid_is_refused():
    assert "Sigma SDMerill (NPL)" in sen.builtin_names()
    with pytest.raises(SpectralError, match="samples cover 400-680 nm"):
        sen.get_sensor("Sigma SDMerill (NPL)")
    # ... but is usable on a grid it covers
    assert sen.get_sensor("Sigma SDMerill (NPL)", SpectralGrid(405, 675, 10)).sensitivities.shape == (28, 3)


def _ok_rgb(wl):
    return np.stack([np.exp(-(((wl - c) / 40) ** 2)) for c in (600, 540, 450)], axis=-1)


@pytest.mark.parametrize("mutate, message", [
    (lambda wl, r: r.__setitem__((10, 0), np.nan), "NaN or inf"),
    (lambda wl, r: r.__setitem__((10, 1), -0.1), "negative sensitivity at"),
    (lambda wl, r: r.__setitem__((slice(None), 2), 0.0), "channel B is all zero"),
])
def test_invalid_sensitivities_are_refused(mutate, message):
    wl = np.arange(380.0, 781.0, 5.0)
    rgb = _ok_rgb(wl)
    mutate(wl, rgb)
    with pytest.raises(SpectralError, match=message):
        sen.sensor_from_samples("bad", wl, rgb)


def test_sensor_channel_dark_on_the_grid_only_is_refused():
    wl = np.arange(380.0, 781.0, 5.0)
    rgb = _ok_rgb(wl)
    rgb[:, 0] = np.where(wl > 720, 1.0, 0.0)  # only infrared response: nothing on 392.5–707.5 nm
    with pytest.raises(SpectralError, match="channel R is all zero on the grid"):
        sen.sensor_from_samples("ir", wl, rgb)


def test_sensor_shape_and_coverage_refusals(tmp_path):
    wl = np.arange(380.0, 781.0, 5.0)
    with pytest.raises(SpectralError, match="need 3 channels"):
        sen.sensor_from_samples("two", wl, _ok_rgb(wl)[:, :2])
    with pytest.raises(SpectralError, match="samples cover 420-780"):
        sen.sensor_from_samples("short", wl[8:], _ok_rgb(wl[8:]))
    with pytest.raises(SpectralError, match="does not exist"):
        sen.get_sensor(str(tmp_path / "missing.json"))
    with pytest.raises(SpectralError, match="unknown sensor 'xyz'.*did you mean 'XYZ'"):
        sen.get_sensor("xyz")


def test_uploaded_sensor_by_name_and_from_bytes():
    wl = np.arange(380.0, 781.0, 5.0)
    rgb = _ok_rgb(wl)
    up = sen.get_sensor("mine", extra={"mine": (wl, rgb * 3.0)})
    assert up.source == "uploaded"
    ref = band_average_fine(interp(wl, rgb, X))
    # atol: the closed-form band integral subtracts running sums of size ≤ ∫ (≈ 70 nm · peak), so
    # its absolute rounding is ≈ 1e-16 · 70 / 5 nm ≈ 1e-15 of the peak; the Gaussian tails go to 1e-40.
    np.testing.assert_allclose(up.sensitivities, ref / ref.max(), rtol=1e-9, atol=1e-13)
    csv = "wavelength,r,g,b\n" + "\n".join(f"{w:g},{a!r},{b!r},{c!r}" for w, (a, b, c) in zip(wl, rgb))
    wl2, rgb2 = sen.read_sensor_file(csv.encode())
    np.testing.assert_array_equal(wl2, wl)
    np.testing.assert_array_equal(rgb2, rgb)


# ============================================================================== reflectances


@pytest.mark.parametrize("name", ["ColorChecker N Ohta", "BabelColor Average"])
def test_colorchecker_sets_are_band_averaged_in_chart_order(name):
    names, r = refl.get_reflectances(name)
    sds = colour.SDS_COLOURCHECKERS[name]
    assert names == list(sds.keys()) and len(names) == 24
    assert names[0] == "dark skin"
    for i, n in enumerate(names):
        ref = band_average_fine(interp(sds[n].wavelengths, sds[n].values, X))
        np.testing.assert_allclose(r[i], ref, rtol=1e-9)


@pytest.mark.parametrize("name, count", [("TCS CIE 1995", 14), ("TCS CIE 2024", 15), ("CQS 9.0", 15),
                                         ("CQS 7.4", 15), ("CIE 2017", 99)])
def test_test_colour_sample_sets(name, count):
    names, r = refl.get_reflectances(name)
    assert len(names) == count and r.shape == (count, 63)
    assert np.all(np.isfinite(r)) and r.min() >= 0 and r.max() <= 1.0


def test_tcs01_values_match_colour_science():
    from colour.quality import datasets as qd

    names, r = refl.get_reflectances("TCS CIE 1995")
    sd = qd.SDS_TCS["CIE 1995"]["TCS01"]
    ref = band_average_fine(interp(sd.wavelengths, sd.values, X))
    np.testing.assert_allclose(r[names.index("TCS01")], ref, rtol=1e-9)


def test_reflectance_csv_is_extended_by_its_end_values(shared_data):
    path = shared_data / "isetcam-spectra/csv/surfaces__reflectances__Objects_Vhrel.csv"  # 400–700 nm
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    names, r = refl.get_reflectances(str(path))
    assert len(names) == 170 and r.shape == (170, 63)
    # np.interp holds the end values outside the samples: the 'constant' policy, independently.
    ref = np.clip(band_average_fine(interp(raw[:, 0], raw[:, 1:], X)).T, 0, None)
    np.testing.assert_allclose(r, ref, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(r[:, 0], np.clip(raw[0, 1:], 0, None), rtol=1e-12)  # band 395 = value at 400


def test_negative_measured_reflectance_is_clipped_and_bad_names_suggested(tmp_path):
    f = tmp_path / "chips.csv"
    f.write_text("wavelength,a,b\n380,0.5,-0.02\n780,0.5,-0.02\n")
    names, r = refl.get_reflectances(str(f))
    assert names == ["a", "b"]
    np.testing.assert_allclose(r[0], 0.5, rtol=1e-12)
    np.testing.assert_array_equal(r[1], 0.0)
    with pytest.raises(SpectralError, match="unknown reflectance set.*did you mean 'ColorChecker N Ohta'"):
        refl.get_reflectances("ColorChecker N Ota")


# =================================================================================== readers


def test_csv_reader_handles_header_comments_blank_lines_and_bom():
    text = "\ufeff# measured 2024\nwavelength, r, g, b\n\n400,1,2,3\n410,4,5,6\n"
    wl, v, names = read_csv_table(text.encode("utf-8"))
    np.testing.assert_array_equal(wl, [400, 410])
    np.testing.assert_array_equal(v, [[1, 2, 3], [4, 5, 6]])
    assert names == ["r", "g", "b"]
    wl, v, names = read_csv_table(b"400,0.5\n500,0.25\n")  # no header
    assert names == ["s0"] and v.shape == (2, 1)


@pytest.mark.parametrize("content, message", [
    (b"", "empty file"),
    (b"wavelength,value\n", "no data rows"),
    (b"400,1\n500,2,3\n", "different numbers of columns"),
    (b"400,1\n500,abc\n", "non-numeric cell"),
    (b"400\n500\n", "need a wavelength column"),
    (b"\xff\xfe\x00bad", "not UTF-8"),
])
def test_csv_reader_refusals(content, message):
    with pytest.raises(SpectralError, match=message):
        read_csv_table(content)


@pytest.mark.parametrize("doc, message", [
    (b"{not json", "not a rawtoaces camera JSON"),
    (b'{"header": {}}', "not a rawtoaces camera JSON"),
    (json.dumps({"spectral_data": {"index": {"main": ["R", "G", "X"]},
                                   "data": {"main": {"400": [1, 2, 3]}}}}).encode(), "not R, G, B"),
    (json.dumps({"spectral_data": {"data": {"main": {"400": [1, 2]}}}}).encode(), "exactly 3 values"),
    (json.dumps({"spectral_data": {"data": {"main": {"abc": [1, 2, 3]}}}}).encode(), "must be numbers"),
])
def test_rawtoaces_reader_refusals(doc, message):
    with pytest.raises(SpectralError, match=message):
        read_rawtoaces_camera(doc)


def test_rawtoaces_reader_returns_header(shared_data):
    wl, rgb, header = read_rawtoaces_camera(shared_data / D810)
    assert header["manufacturer"] == "Nikon" and header["model"] == "D810"
    assert wl[0] == 380 and wl[-1] == 780 and rgb.shape == (wl.size, 3)
