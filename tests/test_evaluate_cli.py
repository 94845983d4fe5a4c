"""``illumix evaluate``: JSON keys the checks rely on, --out files, plug-ins, and one-line errors (exit 2)."""

from __future__ import annotations

import json
import textwrap

import pytest
from cli_testutil import run_cli
from evaluate_testutil import make_lsmi, make_store
from test_cli_spectra import assert_one_line_error
from test_cli_startup import run_fresh

from illumix.awb_eval.methods import load_plugin
from illumix.retarget.errors import SpectralError

KEYS = {"angular_mean", "angular_median", "angular_worst25", "grid_de00_worst25"}

PLUGIN = textwrap.dedent('''
    import numpy as np

    def predict(raw):
        """Gray World by hand: one gain for the image."""
        m = raw.reshape(-1, 3).mean(axis=0)
        return np.broadcast_to(m.max() / m, raw.shape).copy()

    def bad_shape(raw):
        return np.ones((2, 2, 3))

    def negative(raw):
        return -np.ones(raw.shape)

    def crash(raw):
        raise RuntimeError("model weights missing")

    NOT_CALLABLE = 3
''')


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return str(make_store(tmp_path_factory.mktemp("evalcli") / "s"))


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    (tmp_path / "my_awb_model.py").write_text(PLUGIN)
    monkeypatch.chdir(tmp_path)  # plug-ins are found from the current directory
    yield tmp_path


def test_json_has_the_keys_per_method_and_pair(store, capsys, plugin_dir):
    code, out, err = run_cli(capsys, "evaluate", store, "--methods", "gray world, GE1, Patch SoG, WA, GT, my_awb_model:predict",
                             "--pairs", "A,D65;FL11,D50", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert list(doc["methods"]) == ["Gray World", "Gray Edge", "Patch Shades of Gray", "Weighted Average",
                                    "Ground Truth", "my_awb_model:predict"]
    for scores in doc["methods"].values():
        assert KEYS <= set(scores) and scores["images"] == 2
    assert set(doc["pairs"]) == {"A,D65", "FL11,D50"} and KEYS <= set(doc["pairs"]["A,D65"]["Gray World"])
    assert doc["methods"]["Ground Truth"]["angular_mean"] < 1e-3
    # the plug-in is Gray World by hand: the same scores
    assert doc["methods"]["my_awb_model:predict"]["angular_mean"] == pytest.approx(doc["methods"]["Gray World"]["angular_mean"], rel=1e-4)
    assert doc["input"]["kind"] == "store" and len(doc["images"]) == 2


def test_out_writes_table_json_and_plots(store, capsys, tmp_path):
    out = tmp_path / "report"
    code, stdout, err = run_cli(capsys, "evaluate", store, "--methods", "GW,GT", "--pairs", "A,D65", "--out", str(out),
                                "--maps", "1")
    assert code == 0, err
    assert "Gray World" in stdout and "Ground Truth" in stdout  # the table, printed
    assert sorted(p.name for p in out.iterdir()) == ["boxplots.png", "maps", "results.json", "table.md"]
    assert (out / "table.md").read_text().startswith("### AWB evaluation")
    assert KEYS <= set(json.loads((out / "results.json").read_text())["methods"]["Gray World"])
    assert [p.suffix for p in (out / "maps").iterdir()] == [".png"]
    assert not list(out.glob(".*.tmp"))


def test_lsmi_dataset_through_the_cli(tmp_path, capsys):
    root = make_lsmi(tmp_path / "lsmi")
    code, out, err = run_cli(capsys, "evaluate", str(root), "--methods", "GW,GT", "--json", "--split", "test")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["input"]["kind"] == "lsmi" and doc["input"]["camera"] == "cam" and set(doc["pairs"]) == {"12", "123"}
    assert doc["methods"]["Ground Truth"]["angular_worst25"] < 1e-3


@pytest.mark.parametrize("args, expect", [
    (["--methods", "Gray Wrld"], "did you mean 'Gray World'"),
    (["--methods", "nope_module_xyz:predict"], "no module named 'nope_module_xyz'"),
    (["--methods", "my_awb_model:predcit"], "did you mean 'predict'"),
    (["--methods", "my_awb_model:NOT_CALLABLE"], "not a callable"),
    (["--methods", "my_awb_model"], None),  # no colon: an unknown built-in name
    (["--methods", "my_awb_model:bad_shape"], "returned shape (2, 2, 3)"),
    (["--methods", "my_awb_model:negative"], "not finite and positive"),
    (["--methods", "my_awb_model:crash"], "RuntimeError: model weights missing"),
    (["--methods", "GW,grey world"], "named more than once"),
    (["--sensor", "Nikon 5101"], "unknown sensor 'Nikon 5101'"),
    (["--pairs", "A,F11"], "did you mean 'FL11'"),
    (["--split", "test"], "apply to LSMI datasets"),
    (["--grid", "4by4"], "ROWSxCOLS"),
    (["--interpolation", "cubic"], "bilinear or nearest"),
])
def test_bad_input_is_one_line_exit_2(store, capsys, plugin_dir, args, expect):
    line = assert_one_line_error(*run_cli(capsys, "evaluate", store, *args))
    assert expect is None or expect in line, line


@pytest.mark.parametrize("where, expect", [("/proc/illumix-no-such-dir", "cannot write there"),
                                           ("afile/sub", "cannot write there"), ("afile", "is a file")])
def test_unwritable_out_fails_before_scoring(store, capsys, tmp_path, monkeypatch, where, expect):
    """--out is created and probed up front: one line, exit 2, and no image scored first."""
    (tmp_path / "afile").write_text("not a folder")
    monkeypatch.chdir(tmp_path)

    def must_not_score(*args, **kwargs):
        raise AssertionError("scored before checking --out")

    monkeypatch.setattr("illumix.awb_eval.run.evaluate", must_not_score)
    line = assert_one_line_error(*run_cli(capsys, "evaluate", store, "--methods", "GW", "--out", where))
    assert f"--out {where}" in line and expect in line, line
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]  # no probe left behind


def test_neither_store_nor_dataset(tmp_path, capsys):
    line = assert_one_line_error(*run_cli(capsys, "evaluate", str(tmp_path)))
    assert "neither an illumix store" in line
    line = assert_one_line_error(*run_cli(capsys, "evaluate", str(tmp_path / "missing")))
    assert "does not exist" in line


def test_plugin_loader_messages(plugin_dir):
    assert load_plugin("my_awb_model:predict").__name__ == "predict"
    (plugin_dir / "broken_model.py").write_text("import numpy as np\nimport not_installed_dep_xyz\n")
    with pytest.raises(SpectralError, match="importing broken_model failed: No module named 'not_installed_dep_xyz'"):
        load_plugin("broken_model:predict")
    with pytest.raises(SpectralError, match="module.path:callable"):
        load_plugin(":predict")


def test_help_imports_nothing_heavy():
    code, printed, heavy = run_fresh("evaluate", "--help")
    assert code == 0 and "Gray World" in printed and "--methods" in printed
    assert heavy == [], heavy
