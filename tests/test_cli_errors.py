"""Bad input anywhere on the command line: one line ``illumix: error: …`` and exit 2, found before
anything is rendered, served or written; an interrupted command does not exit 0."""

from __future__ import annotations

import os

import pytest

from cli_testutil import run_cli
from test_cli_spectra import assert_one_line_error


def test_ctrl_c_exits_130(capsys, monkeypatch):
    from illumix.retarget import sensors

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sensors, "get_sensor", interrupted)
    code, out, err = run_cli(capsys, "whitepoint", "--sensor", "XYZ", "--illuminant", "A")
    assert code == 130 and err == "illumix: interrupted\n"


@pytest.mark.parametrize("argv", [[], ["store"]])
def test_no_command_prints_help_and_no_empty_error(capsys, argv):
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and "Usage: illumix" in out and err == ""


@pytest.mark.parametrize("argv, needle", [
    (["render", "--demo", "--demo-seed", "-3"], "'--demo-seed'"),
    (["render", "--demo", "--seed", str(2**32)], "'--seed'"),
    (["render", "--demo", "--groups", ","], "--groups ',' names nothing"),
    (["render", "--demo", "--views", ""], "--views '' names nothing"),
    (["render", "{tmp}"], "is a directory; give a YAML or JSON file"),
    (["render", "--demo", "--noise-target", "0.05"], "need wavelengths 'stratified'"),
])
def test_render_refuses_nonsense_before_writing(tmp_path, capsys, argv, needle):
    store = tmp_path / "st"
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    line = assert_one_line_error(*run_cli(capsys, *argv, "--store", str(store), "--dry-run"))
    assert needle in line
    assert not store.exists()


def test_validate_refuses_a_negative_seed(tmp_path, capsys):
    line = assert_one_line_error(*run_cli(capsys, "validate", "--out", str(tmp_path / "v"), "--seed", "-1"))
    assert "'--seed'" in line and not (tmp_path / "v").exists()


def test_unknown_training_set_lists_the_sets(capsys):
    line = assert_one_line_error(*run_cli(capsys, "ccm", "--sensor", "XYZ", "--illuminant", "A", "--training", "nope"))
    assert "unknown reflectance set 'nope' (sets: ColorChecker N Ohta," in line and "CSV file" in line


@pytest.fixture
def blas_env(monkeypatch):
    """main() sets a one-thread BLAS default for demo; keep it out of the other tests' environment."""
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", os.environ.get("OPENBLAS_NUM_THREADS", "1"))


@pytest.mark.parametrize("port", ["99999", "-1"])
def test_demo_refuses_a_bad_port_before_rendering(tmp_path, capsys, blas_env, port):
    store = tmp_path / "st"
    line = assert_one_line_error(*run_cli(capsys, "demo", "--no-serve", "--store", str(store), "--port", port))
    assert "'--port'" in line and not store.exists()


def test_demo_refuses_an_out_that_is_a_file_before_rendering(tmp_path, capsys, blas_env):
    store, out = tmp_path / "st", tmp_path / "out.png"
    out.write_text("")
    line = assert_one_line_error(*run_cli(capsys, "demo", "--no-serve", "--store", str(store), "--out", str(out)))
    assert f"--out {out} is a file" in line and not store.exists()


def test_unreachable_ray_cluster_is_one_line(tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")

    def refuse(**kwargs):
        raise ConnectionError(f"could not connect to {kwargs['address']}\nlong Ray details")

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", refuse)
    code, out, err = run_cli(capsys, "render", "--demo", "--store", str(tmp_path / "st"), "--executor", "ray",
                             "--address", "auto", "--resolution", "8x6", "--spp", "16")
    last = err.strip("\n").split("\n")[-1]  # after the progress bar's line
    assert code == 2 and "Traceback" not in err and last.startswith("illumix: error: render failed: ")
    assert "cannot start or reach the Ray cluster at auto: ConnectionError: could not connect" in last


def test_ray_address_nobody_listens_at_fails_fast(tmp_path, capsys):
    """Ray's own init retries an unreachable HOST:PORT without limit (seen: > 5 min): checked first."""
    pytest.importorskip("ray")
    import socket

    with socket.socket() as s:  # a loopback port nobody listens at
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code, out, err = run_cli(capsys, "render", "--demo", "--store", str(tmp_path / "st"), "--executor", "ray",
                             "--address", f"127.0.0.1:{port}", "--resolution", "8x6", "--spp", "16")
    last = err.strip("\n").split("\n")[-1]
    assert code == 2 and f"cannot reach the Ray cluster at 127.0.0.1:{port}" in last, err
