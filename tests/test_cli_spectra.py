"""The spectral CLI (issue 2, item 5): ``illumix illuminants|sensors list``, ``whitepoint``, ``ccm``.

End-to-end runs go through a real subprocess (the installed console script when on PATH, else
``python -m illumix.cli``); the rest call ``illumix.cli.main`` in-process to keep the suite fast.
Numbers are checked against independent computations from the measured camera file.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import colour
import numpy as np
import pytest

from cli_testutil import run_cli
from independent import band_average_fine, fine_lattice, interp

D810 = "rawtoaces-data/data/camera/Nikon_D810_380_780_5.json"
CAMERA_DIR = "rawtoaces-data/data/camera"


def illumix(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    exe = shutil.which("illumix")
    cmd = [exe, *args] if exe else [sys.executable, "-m", "illumix.cli", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120,
                          env={**os.environ, **(env or {})})


def assert_one_line_error(code: int, out: str, err: str) -> str:
    assert code == 2, (code, err)
    assert out == ""
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("illumix: error: ")
    return lines[0]


def _d810_white_point(path, illuminant):
    doc = json.loads(path.read_text())
    table = doc["spectral_data"]["data"]["main"]
    wl = np.array([float(k) for k in table])
    x = fine_lattice()
    cam = band_average_fine(interp(wl, np.array(list(table.values()), dtype=float), x))
    sd = colour.SDS_ILLUMINANTS[illuminant]
    w = band_average_fine(interp(sd.wavelengths, sd.values, x)) @ cam
    return w / w[1]


# ------------------------------------------------------------------------------ whitepoint


def test_whitepoint_json_for_a_rawtoaces_file_end_to_end(shared_data):
    path = shared_data / D810
    r = illumix("whitepoint", "--sensor", str(path), "--illuminant", "A", "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    assert {"rgb", "r_over_g", "b_over_g"} <= set(doc)
    ref = _d810_white_point(path, "A")
    # Band averages recomputed independently by the fine trapezoid rule: float rounding only.
    np.testing.assert_allclose(doc["rgb"], ref, rtol=1e-9)
    assert doc["rgb"][1] == 1.0
    assert doc["r_over_g"] == doc["rgb"][0] and doc["b_over_g"] == doc["rgb"][2]
    # Tungsten on a Bayer DSLR: R/G below 1 (green dominates) but far above B/G.
    assert 0.5 < doc["r_over_g"] < 1.2 and 0.2 < doc["b_over_g"] < 0.7


def test_whitepoint_human_output(capsys, shared_data):
    code, out, err = run_cli(capsys, "whitepoint", "--sensor", str(shared_data / D810), "--illuminant", "D65")
    assert code == 0 and err == ""
    ref = _d810_white_point(shared_data / D810, "D65")
    assert f"R/G = {ref[0]:.5f}" in out and f"B/G = {ref[2]:.5f}" in out


def test_whitepoint_by_folder_name(capsys, shared_data, monkeypatch):
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(shared_data / CAMERA_DIR))
    code, out, _ = run_cli(capsys, "whitepoint", "--sensor", "Nikon_D810", "--illuminant", "FL11", "--json")
    assert code == 0
    np.testing.assert_allclose(json.loads(out)["rgb"], _d810_white_point(shared_data / D810, "FL11"), rtol=1e-9)


# ------------------------------------------------------------------------------------- ccm


def test_ccm_json_end_to_end(shared_data):
    r = illumix("ccm", "--sensor", str(shared_data / D810), "--illuminant", "D65", "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    m = np.array(doc["matrix"])
    assert m.shape == (3, 3)
    np.testing.assert_allclose(m.sum(axis=1), 1.0, atol=1e-7)  # white preserving (rounded to 1e-8)
    assert np.all(np.diag(m) > 1.0)
    assert isinstance(doc["fit_delta_e00_mean"], float)
    assert 0.2 < doc["fit_delta_e00_mean"] < 2.0  # a real DSLR through a 3×3 matrix: a few ΔE00 at most


def test_ccm_xyz_sensor_is_nearly_exact(capsys):
    code, out, _ = run_cli(capsys, "ccm", "--sensor", "XYZ", "--illuminant", "D65", "--json")
    assert code == 0
    doc = json.loads(out)
    # An exact linear map XYZ → sRGB exists; only the band approximation is left (see test_physics).
    assert doc["fit_delta_e00_mean"] < 0.05
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    xyz_w = colour.sd_to_XYZ(colour.SDS_ILLUMINANTS["D65"])
    xyz_w = xyz_w / xyz_w[1]
    # Under D65 the adaptation is (nearly) the identity: M ≈ M_sRGB · diag(XYZ_w); the white point
    # of the integration differs from sRGB's D65 xy by ~1e-4 and the band approximation by ~1e-3.
    np.testing.assert_allclose(doc["matrix"], srgb.matrix_XYZ_to_RGB @ np.diag(xyz_w), atol=1e-2)


def test_ccm_options_and_human_output(capsys):
    code, out, _ = run_cli(capsys, "ccm", "--sensor", "XYZ", "--illuminant", "A", "--training",
                            "TCS CIE 1995", "--method", "Unconstrained")
    assert code == 0
    assert "fit ΔE00 on TCS CIE 1995" in out
    rows = [line for line in out.splitlines() if line.strip().startswith(("+", "-"))]
    assert len(rows) == 3


# ------------------------------------------------------------------------------------ lists


def test_illuminants_list_json(capsys):
    code, out, _ = run_cli(capsys, "illuminants", "list", "--json")
    assert code == 0
    doc = json.loads(out)
    assert {"A", "D65", "FL11", "LED-B1"} <= set(doc["illuminants"])
    # Every colour-science illuminant is listed: usable ones, or with the reason it is not.
    assert set(doc["illuminants"]) | set(doc["not_on_grid"]) == set(colour.SDS_ILLUMINANTS.keys())
    assert all("392.5-707.5 nm" in why for why in doc["not_on_grid"].values())
    assert not any(n.startswith(("D", "FL", "LED")) for n in doc["not_on_grid"])
    assert doc["parametric"]["blackbody"]["min_kelvin"] == 500.0
    assert doc["parametric"]["daylight"]["max_kelvin"] == 25000.0


def test_sensors_list_json_reports_usability(capsys, shared_data, monkeypatch):
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(shared_data / CAMERA_DIR))
    code, out, _ = run_cli(capsys, "sensors", "list", "--json")
    assert code == 0
    rows = {r["name"]: r for r in json.loads(out)["sensors"]}
    assert rows["XYZ"]["ok"] and rows["Nikon_D810"]["ok"]
    assert not rows["Sigma SDMerill (NPL)"]["ok"]
    assert "400-680 nm" in rows["Sigma SDMerill (NPL)"]["problem"]
    assert len(rows) >= 3 + 50  # the 52 rawtoaces cameras (a few may not cover the grid)


def test_sensors_list_human_output(capsys):
    code, out, _ = run_cli(capsys, "sensors", "list")
    assert code == 0 and "XYZ" in out


# ----------------------------------------------------------------------------------- errors


def test_unknown_illuminant_is_one_line_with_a_suggestion_end_to_end():
    r = illumix("whitepoint", "--sensor", "XYZ", "--illuminant", "D6")
    line = assert_one_line_error(r.returncode, r.stdout, r.stderr)
    assert "unknown illuminant 'D6'" in line and "did you mean" in line and "'D65'" in line


@pytest.mark.parametrize("args, expected", [
    (("whitepoint", "--sensor", "xyz", "--illuminant", "A"), "did you mean 'XYZ'"),
    (("ccm", "--sensor", "XYZ", "--illuminant", "FL13"), "'FL1"),
    (("ccm", "--sensor", "XYZ", "--illuminant", "D65", "--training", "ColorChecker N Ota"),
     "did you mean 'ColorChecker N Ohta'"),
    (("ccm", "--sensor", "XYZ", "--illuminant", "D65", "--method", "Gray World"), "unknown CCM method"),
    (("whitepoint", "--sensor", "XYZ", "--illuminant", "blackbody:100"), "outside 500-50000 K"),
    (("whitepoint", "--sensor", "/no/such/camera.json", "--illuminant", "A"), "does not exist"),
    (("whitepoint", "--sensor", "Sigma SDMerill (NPL)", "--illuminant", "A"), "samples cover 400-680 nm"),
])
def test_errors_are_one_line_exit_2(capsys, args, expected):
    line = assert_one_line_error(*run_cli(capsys, *args))
    assert expected in line


def test_unknown_sensor_name_suggests_a_folder_camera(capsys, shared_data, monkeypatch):
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(shared_data / CAMERA_DIR))
    line = assert_one_line_error(*run_cli(capsys, "whitepoint", "--sensor", "Nikon_D81", "--illuminant", "A"))
    assert "unknown sensor 'Nikon_D81'" in line and "'Nikon_D810'" in line


def test_bad_sensor_file_is_one_line(capsys, tmp_path):
    f = tmp_path / "cam.csv"
    f.write_text("wavelength,r,g,b\n380,1,1,1\n500,1,-1,1\n780,1,1,1\n")
    line = assert_one_line_error(*run_cli(capsys, "whitepoint", "--sensor", str(f), "--illuminant", "A"))
    assert "negative sensitivity at 500 nm" in line


@pytest.mark.parametrize("args", [("whitepoint", "--sensor", "XYZ"), ("frobnicate",)])
def test_usage_errors_are_one_line_exit_2(capsys, args):
    assert_one_line_error(*run_cli(capsys, *args))
