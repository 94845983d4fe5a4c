"""``illumix store verify``/``info`` through the real entry point: exit codes and the JSON report.

A damaged store must fail the process (exit 1), not only print the problem: scripts and CI check
the exit status. Runs ``python -m illumix.cli`` in a subprocess from the repository root so the
code under test, not an installed copy, answers.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import synthetic_store
from conftest import REPO_ROOT


def illumix(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "illumix.cli", *args], capture_output=True, text=True,
                          timeout=120, cwd=REPO_ROOT)


@pytest.fixture(scope="module")
def stores(tmp_path_factory) -> tuple[Path, Path]:
    """(an intact store, the same store with one chunk of cube synth/v0/lamp overwritten)."""
    root = tmp_path_factory.mktemp("stores")
    good, bad = root / "good", root / "bad"
    synthetic_store.build(good, extras=False)
    synthetic_store.build(bad, extras=False)
    chunk = next(p for p in sorted((bad / "scenes/synth/v0/cubes/lamp/data/c").rglob("*")) if p.is_file())
    data = bytearray(chunk.read_bytes())
    data[16:64] = b"\xff" * 48
    chunk.write_bytes(bytes(data))
    return good, bad


def test_verify_damaged_store_exits_1(stores):
    r = illumix("store", "verify", str(stores[1]))
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "PROBLEM scenes/synth/v0/cubes/lamp/data/c/0/0/0: fails its checksum" in r.stdout  # the file
    assert "PROBLEM scenes/synth/v0/cubes/lamp: unreadable" in r.stdout  # and the cube it breaks
    assert "2 problem(s)" in r.stdout and "Traceback" not in r.stderr


def test_verify_damaged_store_json_lists_the_problem_and_exits_1(stores):
    r = illumix("store", "verify", str(stores[1]), "--json")
    assert r.returncode == 1, r.stderr
    doc = json.loads(r.stdout)  # stdout holds the report and nothing else
    assert doc["ok"] is False
    assert [p["where"] for p in doc["problems"]] == ["scenes/synth/v0/cubes/lamp/data/c/0/0/0",
                                                     "scenes/synth/v0/cubes/lamp"]
    assert "fails its checksum" in doc["problems"][0]["what"] and doc["problems"][1]["what"].startswith("unreadable")


@pytest.mark.parametrize("json_flag", [[], ["--json"]])
def test_verify_intact_store_exits_0(stores, json_flag):
    r = illumix("store", "verify", str(stores[0]), *json_flag)
    assert r.returncode == 0, (r.stdout, r.stderr)
    if json_flag:
        doc = json.loads(r.stdout)
        assert doc["ok"] is True and doc["problems"] == [] and doc["checked"]["cubes"] == 2
    else:
        assert r.stdout.startswith("OK: checked 1 views")


def test_verify_missing_store_is_one_line_exit_2(tmp_path):
    r = illumix("store", "verify", str(tmp_path / "typo"), "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith("illumix: error: no illumix store at") and r.stderr.count("\n") == 1


def test_verify_reports_corrupt_group_metadata(tmp_path):
    """A sibling of the exit-code defect: corrupt metadata of an intermediate group (which zarr
    itself then refuses to open) is a problem too, not an OK."""
    path = tmp_path / "store"
    synthetic_store.build(path, extras=False)
    (path / "scenes" / "zarr.json").write_text("{ not json")
    r = illumix("store", "verify", str(path), "--json")
    assert r.returncode == 1
    assert any(p["where"] == "scenes" for p in json.loads(r.stdout)["problems"])
