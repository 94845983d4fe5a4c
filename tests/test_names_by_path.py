"""Issue 36 item 8: ``illumix export`` and ``illumix evaluate`` take sensors and illuminants given by path,
as every other command does, through one resolver (:class:`engine.local_library.LocalLibrary`, which
reads files with :mod:`retarget.sensors` / :mod:`retarget.illuminants` like ``whitepoint`` does); a
missing file is one line naming its path. The service keeps refusing paths (a request must not read
the server's files)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_testutil import run_cli
from test_cli_spectra import assert_one_line_error

CAMERA = "Nikon 5100 (NPL)"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A rawtoaces camera JSON with the curves of the built-in ``Nikon 5100 (NPL)`` and an FL2 CSV,
    in a folder that is not on ILLUMIX_SENSOR_PATH."""
    import colour

    d = tmp_path_factory.mktemp("elsewhere")
    cam = colour.MSDS_CAMERA_SENSITIVITIES[CAMERA]
    doc = {"header": {"manufacturer": "test", "model": "by path"},
           "spectral_data": {"units": "relative", "index": {"main": ["R", "G", "B"]},
                             "data": {"main": {f"{w:g}": [float(v) for v in row]
                                               for w, row in zip(cam.wavelengths, cam.values)}}}}
    (d / "My_Cam_380_780_5.json").write_text(json.dumps(doc))
    sd = colour.SDS_ILLUMINANTS["FL2"]
    (d / "my_fl2.csv").write_text("\n".join(f"{w:g},{v:.6g}" for w, v in zip(sd.wavelengths, sd.values)) + "\n")
    return {"camera": str(d / "My_Cam_380_780_5.json"), "light": str(d / "my_fl2.csv"), "dir": d}


@pytest.fixture(autouse=True)
def no_sensor_path(monkeypatch):
    monkeypatch.delenv("ILLUMIX_SENSOR_PATH", raising=False)


@pytest.fixture(scope="module")
def export_store(tmp_path_factory):
    pytest.importorskip("rawpy")
    from export_testutil import build_export_store

    return build_export_store(tmp_path_factory.mktemp("names") / "store")


@pytest.fixture(scope="module")
def eval_store(tmp_path_factory):
    from evaluate_testutil import make_store

    return str(make_store(tmp_path_factory.mktemp("names-eval") / "store"))


def test_one_resolver_takes_files_and_the_service_library_does_not(export_store, files):
    from illumix.engine.library import Library
    from illumix.engine.local_library import LocalLibrary
    from illumix.retarget.errors import SpectralError, UnknownName
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor
    from illumix.store import CubeStore

    st = CubeStore.open(export_store, mode="r")
    local = LocalLibrary(st)
    s, key = local.sensor(files["camera"], DEFAULT_GRID)
    assert s.name == "My_Cam" and key.startswith("file:") and s.source.endswith("My_Cam_380_780_5.json")
    np.testing.assert_allclose(s.sensitivities, get_sensor(CAMERA, DEFAULT_GRID).sensitivities, atol=1e-12)
    spd, ikey = local.illuminant(files["light"], DEFAULT_GRID)
    np.testing.assert_allclose(spd, illuminant_spd("FL2", DEFAULT_GRID), rtol=1e-5)
    assert ikey != local.illuminant("FL2", DEFAULT_GRID)[1]
    assert local.sensor(CAMERA, DEFAULT_GRID)[1] == Library(st).sensor(CAMERA, DEFAULT_GRID)[1]  # names unchanged
    for what, name in (("sensor", files["camera"]), ("illuminant", files["light"])):
        with pytest.raises(UnknownName):  # the service never reads a path it is sent
            getattr(Library(st), what)(name, DEFAULT_GRID)
    with pytest.raises(SpectralError, match="does not exist; check the path"):
        local.sensor(str(files["dir"] / "nope.json"), DEFAULT_GRID)


def test_export_takes_a_camera_json_and_an_illuminant_csv_by_path(export_store, files, tmp_path, capsys):
    import cv2

    common = ["--count", "1", "--size", "32x24", "--seed", "3", "--json", "--noise", "none"]
    code, out, err = run_cli(capsys, "export", export_store, str(tmp_path / "path"), "--sensors", files["camera"],
                             "--pairs", f"{files['light']},D65", *common)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["cameras"][0]["folder"] == "My-Cam"  # named by the file's stem, as ILLUMIX_SENSOR_PATH names it
    meta = json.loads((tmp_path / "path" / "My-Cam" / "meta.json").read_text())
    (place, entry), = meta.items()
    assert [i["name"] for i in entry["Illuminants"]] == [files["light"], "D65"]
    # the same curves by name and by path: the same frames
    code, _, err = run_cli(capsys, "export", export_store, str(tmp_path / "name"), "--sensors", CAMERA,
                           "--pairs", "FL2,D65", *common)
    assert code == 0, err
    tiffs = sorted((tmp_path / "path" / "My-Cam" / place).glob("*.tiff"))
    assert tiffs
    for t in tiffs:
        by_name = cv2.imread(str(tmp_path / "name" / "Nikon-5100-NPL" / place / t.name), cv2.IMREAD_UNCHANGED)
        by_path = cv2.imread(str(t), cv2.IMREAD_UNCHANGED)
        assert np.abs(by_name.astype(int) - by_path.astype(int)).max() <= 1


def test_evaluate_takes_a_camera_json_and_an_illuminant_csv_by_path(eval_store, files, capsys):
    def scores(sensor: str, pair: str) -> list:
        code, out, err = run_cli(capsys, "evaluate", eval_store, "--methods", "GW,GT", "--sensor", sensor,
                                 "--pairs", pair, "--json")
        assert code == 0, err
        doc = json.loads(out)
        assert len(doc["images"]) == 1 and doc["input"]["sensor"] == sensor
        return doc["methods"]

    by_path = scores(files["camera"], f"{files['light']},D65")
    by_name = scores(CAMERA, "FL2,D65")
    assert by_path.keys() == by_name.keys()
    for m in by_name:
        assert by_path[m]["angular_mean"] == pytest.approx(by_name[m]["angular_mean"], abs=1e-3)


@pytest.mark.parametrize("command, flag, value, says", [
    ("export", "--sensors", "{dir}/missing.json", "sensor file '{dir}/missing.json' does not exist"),
    ("export", "--pairs", "{dir}/missing.csv,D65", "illuminant file '{dir}/missing.csv' does not exist"),
    ("evaluate", "--sensor", "{dir}/missing.json", "sensor file '{dir}/missing.json' does not exist"),
    ("evaluate", "--pairs", "{dir}/missing.csv,D65", "illuminant file '{dir}/missing.csv' does not exist"),
])
def test_a_missing_file_is_one_line_naming_the_path(export_store, eval_store, files, tmp_path, capsys,
                                                    command, flag, value, says):
    d = files["dir"]
    args = [export_store, str(tmp_path / "o")] if command == "export" else [eval_store]
    line = assert_one_line_error(*run_cli(capsys, command, *args, flag, value.format(dir=d)))
    assert says.format(dir=d) in line
    assert not (tmp_path / "o").exists()
