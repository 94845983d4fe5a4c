"""``illumix serve``: a path without a store is refused before anything starts (unless --create), and
an empty token, which turns authentication off, is said on stderr. uvicorn never runs here:
``uvicorn.run`` is replaced by a recorder."""

from __future__ import annotations

import os
import socket

import pytest

import synthetic_store
from cli_testutil import run_cli
from illumix.store import CubeStore

# Port 0: the address check binds before uvicorn would, and a fixed port may be in use here.
SERVE = ("serve", "--port", "0")


@pytest.fixture
def served(monkeypatch) -> list[dict]:
    """Calls of ``uvicorn.run`` (app, host, port), instead of serving."""
    import uvicorn

    calls: list[dict] = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: calls.append({"app": app, **kw}))
    monkeypatch.delenv("ILLUMIX_TOKEN", raising=False)
    # main() sets a one-thread BLAS default for serve; keep it out of the other tests' environment.
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    return calls


def test_missing_store_is_refused_before_uvicorn_starts(tmp_path, capsys, served):
    typo = tmp_path / "typo"
    code, out, err = run_cli(capsys, *SERVE, "--store", str(typo))
    assert code == 2 and out == "" and not served
    assert err.count("\n") == 1 and err.startswith(f"illumix: error: no illumix store at {typo}")
    assert "illumix render --store" in err and "--create" in err
    assert not typo.exists()


def test_non_store_directory_is_refused(tmp_path, capsys, served):
    (tmp_path / "notes.txt").write_text("not a store")
    code, out, err = run_cli(capsys, *SERVE, "--store", str(tmp_path), "--create")
    assert code == 2 and not served and "is not empty and is not an illumix store" in err


def test_create_serves_a_new_empty_store(tmp_path, capsys, served):
    path = tmp_path / "new"
    code, out, err = run_cli(capsys, *SERVE, "--store", str(path), "--create")
    assert code == 0, err
    assert CubeStore.exists(str(path)) and CubeStore.open(str(path), mode="r").scenes() == []
    assert len(served) == 1 and served[0]["port"] == 0 and served[0]["host"] == "127.0.0.1"
    assert "warning" not in err


def test_existing_store_is_served(tmp_path, capsys, served):
    synthetic_store.build(tmp_path / "st", extras=False)
    code, out, err = run_cli(capsys, *SERVE, "--store", str(tmp_path / "st"), "--token", "s3cret")
    assert code == 0 and err == "" and len(served) == 1


def _write_is_open(app) -> bool:
    """Whether an upload without credentials gets past the token check (anything but 401)."""
    from fastapi.testclient import TestClient

    r = TestClient(app).delete("/sensors/nothing-here")
    return r.status_code != 401


@pytest.mark.parametrize("how", ["option", "env"])
def test_empty_token_warns_that_writes_are_open(tmp_path, capsys, served, monkeypatch, how):
    synthetic_store.build(tmp_path / "st", extras=False)
    args = [*SERVE, "--store", str(tmp_path / "st")]
    if how == "option":
        args += ["--token", ""]
    else:
        monkeypatch.setenv("ILLUMIX_TOKEN", "")
    code, out, err = run_cli(capsys, *args)
    assert code == 0 and len(served) == 1
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1 and lines[0].startswith("illumix: warning: the token is empty")
    assert "uploads and deletes are open to anyone" in lines[0]
    assert _write_is_open(served[0]["app"])


def test_a_token_closes_writes(tmp_path, capsys, served, monkeypatch):
    synthetic_store.build(tmp_path / "st", extras=False)
    monkeypatch.setenv("ILLUMIX_TOKEN", "s3cret")
    code, out, err = run_cli(capsys, *SERVE, "--store", str(tmp_path / "st"))
    assert code == 0 and err == ""
    assert not _write_is_open(served[0]["app"])


def test_bad_host_or_taken_port_is_one_line_before_anything_starts(tmp_path, capsys, served):
    new = ("--store", str(tmp_path / "new"), "--create")
    code, out, err = run_cli(capsys, "serve", *new, "--host", "no.such.host.invalid")
    assert code == 2 and err.count("\n") == 1 and "--host 'no.such.host.invalid' is not an address" in err
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code, out, err = run_cli(capsys, "serve", *new, "--port", str(port))
    assert code == 2 and err.count("\n") == 1 and f"cannot listen on 127.0.0.1:{port}" in err
    assert not served and not (tmp_path / "new").exists()


def test_warm_is_listed_in_help(capsys):
    code, out, _ = run_cli(capsys, "serve", "--help")
    assert code == 0 and "--warm" in out


def test_warm_fills_the_cache_before_serving(tmp_path, capsys, served):
    """--warm decodes before uvicorn starts: one line per entry on stderr, and the first sample is all hits."""
    from fastapi.testclient import TestClient

    synthetic_store.build(tmp_path / "st", illumination=True)
    code, _, err = run_cli(capsys, *SERVE, "--store", str(tmp_path / "st"), "--token", "s3cret", "--warm")
    assert code == 0 and len(served) == 1, err
    lines = err.strip("\n").split("\n")
    assert all(line.startswith("illumix: warm: ") for line in lines) and "synth/v0 window transport" in err
    c = TestClient(served[0]["app"])
    assert c.get("/sample", params={"scene": "synth", "view": "v0", "crop": "0,0,16,16"}).status_code == 200
    metrics = dict(line.rsplit(" ", 1) for line in c.get("/metrics").text.splitlines() if not line.startswith("#"))
    assert float(metrics["illumix_cache_hits_total"]) > 0 and float(metrics["illumix_cache_misses_total"]) == 0
