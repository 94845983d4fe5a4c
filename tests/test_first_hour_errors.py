"""Issue 38, the first hour: errors that name the real cause and offer close matches for every name
(sensors included: built-in, measured cameras of ILLUMIX_SENSOR_PATH, uploads); an export that warns
about an empty split and an evaluation that says the split is empty; and the cosmetics: tables at
their full width when piped, ``illumix --help`` summaries whole, ``validate``'s table on stdout."""

from __future__ import annotations

import io
import json
from types import SimpleNamespace

import numpy as np
import pytest
from cli_testutil import run_cli
from illumix.retarget.errors import close_matches, unknown_name
from server_testutil import synthetic_service_fixtures

TOKEN = "t0ken"
SENSOR_CSV = "wavelength,r,g,b\n" + "\n".join(
    f"{wl},{np.exp(-((wl - 600) / 40) ** 2):.6f},{np.exp(-((wl - 540) / 40) ** 2):.6f},"
    f"{np.exp(-((wl - 460) / 30) ** 2):.6f}" for wl in range(380, 785, 5))

store_path, client = synthetic_service_fixtures("errs38", TOKEN)


# -- close matches -------------------------------------------------------------------------------
@pytest.mark.parametrize("typed, known, expect", [
    ("Nikon", ["XYZ", "Nikon 5100 (NPL)", "Sigma SDMerill (NPL)"], ["Nikon 5100 (NPL)"]),  # a prefix
    ("sigma", ["XYZ", "Nikon 5100 (NPL)", "Sigma SDMerill (NPL)"], ["Sigma SDMerill (NPL)"]),
    ("merill", ["XYZ", "Sigma SDMerill (NPL)"], ["Sigma SDMerill (NPL)"]),  # a part of the name
    ("nikn", ["XYZ", "Nikon 5100 (NPL)"], ["Nikon 5100 (NPL)"]),  # a word, mistyped
    ("XZY", ["XYZ", "Nikon 5100 (NPL)"], ["XYZ"]),  # the whole name, mistyped (as before)
    ("canon", ["XYZ", "Nikon 5100 (NPL)"], []),  # nothing close: nothing offered
    ("demo", [f"demo-room-{i}" for i in range(50)], ["demo-room-0", "demo-room-1", "demo-room-2"]),  # at most 3
])
def test_close_matches(typed, known, expect):
    assert close_matches(typed, known) == expect


def test_unknown_sensor_offers_the_camera_a_prefix_names():
    from illumix.retarget.sensors import get_sensor

    with pytest.raises(Exception, match=r"unknown sensor 'Nikon'; did you mean 'Nikon 5100 \(NPL\)'"):
        get_sensor("Nikon")
    assert "did you mean" not in str(unknown_name("sensor", "canon", ["XYZ", "Nikon 5100 (NPL)"]))


def test_store_names_get_the_same_close_matches():
    from illumix.store import StoreKeyError

    err = StoreKeyError("scene", "kitchen", ["demo", "kitchen-0001-evening"], "the store")
    assert "did you mean 'kitchen-0001-evening'" in str(err)


# -- the service: /sample and /sensors/{name} ------------------------------------------------------
def _detail(resp) -> str:
    assert resp.status_code == 404, resp.text
    return resp.json()["detail"]


def test_sample_with_a_sensor_prefix_offers_the_builtin(client):
    detail = _detail(client.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "Nikon"}))
    assert "unknown sensor 'Nikon'" in detail and "did you mean 'Nikon 5100 (NPL)'" in detail
    assert "did you mean 'Nikon 5100 (NPL)'" in _detail(client.get("/sensors/Nikon"))


def test_sample_offers_measured_cameras_of_the_sensor_path(client, tmp_path, monkeypatch):
    (tmp_path / "Canon EOS 5D Mark II.json").write_text("{}")  # listed by its name; never read here
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(tmp_path))
    detail = _detail(client.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "canon"}))
    assert "did you mean 'Canon EOS 5D Mark II'" in detail


def test_sample_offers_uploaded_sensors(client):
    r = client.post("/sensors", data={"name": "lab-camera-7"}, files={"file": ("c.csv", SENSOR_CSV)},
                    headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 201, r.text
    detail = _detail(client.get("/sample", params={"scene": "synth", "view": "v0", "sensor": "lab-camera"}))
    assert "did you mean 'lab-camera-7'" in detail


# -- export warns, evaluate names the empty split ---------------------------------------------------
@pytest.fixture(scope="module")
def one_scene_store(tmp_path_factory):
    import synthetic_store

    path = tmp_path_factory.mktemp("one_scene") / "store"
    synthetic_store.build(path, extras=False, illumination=True)  # scene synth, view v0 only
    return str(path)


@pytest.fixture(scope="module")
def one_scene_export(one_scene_store, tmp_path_factory):
    pytest.importorskip("cv2")
    capsys = _Capture()
    out = tmp_path_factory.mktemp("one_scene_lsmi") / "out"
    code, _, err = capsys.run("export", one_scene_store, str(out), "--format", "lsmi")
    assert code == 0, err
    return out, err


class _Capture:
    """``run_cli`` for a module fixture (pytest's capsys is function-scoped): stdout/stderr swapped."""

    def run(self, *argv: str) -> tuple[int, str, str]:
        import contextlib

        from illumix.cli import main

        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(list(argv))
                code = 0
            except SystemExit as exc:
                code = int(exc.code or 0)
        return code, out.getvalue(), err.getvalue()


def test_export_of_one_scene_warns_that_val_and_test_are_empty(one_scene_export):
    out, err = one_scene_export
    warned = [line for line in err.splitlines() if line.startswith("illumix: warning: ")]
    assert len(warned) == 1 and "the val and test splits are empty" in warned[0], err
    assert "train 1, val 0, test 0" in warned[0] and "--split 1,0,0" in warned[0]
    card = (out / "README.md").read_text()
    assert "note: the val and test splits are empty" in card


def test_export_with_the_splits_asked_for_does_not_warn(one_scene_store, tmp_path):
    pytest.importorskip("cv2")
    code, _, err = _Capture().run("export", one_scene_store, str(tmp_path / "o"), "--format", "lsmi",
                                  "--split", "1,0,0")
    assert code == 0, err
    assert "split is empty" not in err


def test_evaluate_an_empty_split_names_the_cause(one_scene_export, capsys):
    out, _ = one_scene_export
    code, stdout, err = run_cli(capsys, "evaluate", str(out), "--methods", "GW", "--split", "test")
    assert code == 2 and stdout == "", err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("illumix: error: "), err
    assert "the test split is empty" in err and "train 1" in err
    assert "LSMI light sets are digits" not in err


# -- cosmetics -------------------------------------------------------------------------------------
def test_piped_console_is_wide_and_rules_stay_80():
    from rich.table import Table

    from illumix.consoles import PIPE_WIDTH, PipeAwareConsole

    buf = io.StringIO()  # not a terminal
    c = PipeAwareConsole(file=buf, _environ={})
    assert c.width == PIPE_WIDTH
    name = "demo-" + "kitchen-" * 15  # 125 characters: rich cut it to "demo-…" at 80 columns
    t = Table("scene", "views")
    t.add_row(name, "3")
    c.print(t)
    c.rule("next")
    lines = buf.getvalue().splitlines()
    assert any(name in line for line in lines) and "…" not in buf.getvalue()
    assert len(lines[-1]) == 80  # the rule
    assert PipeAwareConsole(file=io.StringIO(), _environ={"COLUMNS": "100"}).width == 100  # COLUMNS wins
    assert PipeAwareConsole(file=io.StringIO(), width=90).width == 90


def test_piped_sensors_table_is_not_cut(capsys, tmp_path, monkeypatch):
    name = "Nikon-D810-measured-at-the-lab-under-monochromator-2024-series-" + "x" * 30
    (tmp_path / f"{name}.csv").write_text(SENSOR_CSV)
    monkeypatch.setenv("ILLUMIX_SENSOR_PATH", str(tmp_path))
    code, out, err = run_cli(capsys, "sensors", "list")
    assert code == 0, err
    assert any(name in line for line in out.splitlines()), out


def test_top_level_help_summaries_are_whole(capsys):
    code, out, err = run_cli(capsys, "--help")
    assert code == 0, err
    assert "(thesis eq. 3.2)" in out and "(thesis eq.\n" not in out
    commands = out.split("Commands:")[1]
    assert "..." not in commands, commands  # click's cut at 45 characters


def test_summary_keeps_abbreviations():
    from illumix.cli import summary

    assert summary("White point (thesis eq. 3.2): R/G. More text.\n\nDetails.") == "White point (thesis eq. 3.2): R/G."
    assert summary("One line only") == "One line only"


def test_validate_prints_its_table_on_stdout(capsys, tmp_path, monkeypatch):
    from illumix.renderer_jobs import validate

    from illumix import cmd_render

    row = {"illuminant": "D65", "mean_delta_e00": 0.01, "max_delta_e00": 0.02, "mean_relative_rg_bg_pct": 0.1,
           "mean_angular_deg": 0.05}
    result = SimpleNamespace(summary=[row], to_dict=lambda: {"summary": [row]})
    monkeypatch.setattr(validate, "run_validation", lambda *a, **k: result)
    monkeypatch.setattr(cmd_render, "require_renderer", lambda backend: None)
    code, out, err = run_cli(capsys, "validate", "--out", str(tmp_path / "v"), "--illuminants", "D65")
    assert code == 0, err
    assert "mean ΔE00" in out and "D65" in out and "0.0100" in out  # the result, on stdout
    assert "mean ΔE00" not in err and "wrote" in err and "validation.json" in err
    assert json.loads((tmp_path / "v" / "validation.json").read_text())["summary"] == [row]
