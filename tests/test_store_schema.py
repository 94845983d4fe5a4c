"""Schema versions, missing attributes, corrupt or missing chunks: clear errors naming the node, and
``illumix store verify`` (store.report.verify and the CLI) catching each of them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import typer
from pydantic import ValidationError
from store_testutil import NB, add_view, cube, meta, new_store
from typer.testing import CliRunner

from illumix import cmd_store
from illumix.retarget.grid import SpectralGrid
from illumix.store.checksums import MANIFEST, manifest_bytes, sha256
from illumix.store import CubeMeta, CubeStore, StoreError
from illumix.store.report import verify

REPO = Path(__file__).resolve().parents[1]
CUBE = "scenes/s/v/cubes/g"


def _app() -> typer.Typer:
    app = typer.Typer()
    cmd_store.register(app)
    app.command("noop", hidden=True)(lambda: None)  # keep `store` a sub-command group
    return app


@pytest.fixture
def store_path(tmp_path) -> Path:
    st = new_store(tmp_path / "st")
    rng = np.random.default_rng(0)
    add_view(st, aovs={"depth": rng.random((48, 80)), "mask": rng.random((48, 80)) > 0.5})
    st.write_cube("s", "v", "g", cube(), meta(emission_name="flat"))
    st.mark_empty("s", "v", "off", meta())
    st.registry("sensors").put("cam-1", b"wavelength,r,g,b\n400,0.1,0.2,0.3\n", "csv")
    return tmp_path / "st"


def _edit(path: Path, fn) -> None:
    """Rewrite a metadata document as a writer would (its node's manifest re-sealed), so the checks
    below the checksums are what is tested (tests/test_store_checksums.py tests the checksums)."""
    js = json.loads(path.read_text())
    fn(js["attributes"])
    path.write_text(json.dumps(js))
    node = path.parent
    if (node / MANIFEST).is_file():
        files = sorted(str(f.relative_to(node)) for f in node.rglob("*") if f.is_file()
                       and not str(f.relative_to(node)).startswith("_checksums"))
        (node / MANIFEST).write_bytes(manifest_bytes({f: sha256((node / f).read_bytes()) for f in files}))


def _problems(p: Path) -> list[str]:
    rep = verify(CubeStore.open(p, mode="r"))
    assert rep["ok"] == (not rep["problems"])
    return [f"{x['where']}: {x['what']}" for x in rep["problems"]]


def test_clean_store_verifies_and_cli_reports(store_path):
    assert _problems(store_path) == []
    r = CliRunner().invoke(_app(), ["store", "verify", str(store_path)])
    assert r.exit_code == 0 and "OK" in r.output
    r = CliRunner().invoke(_app(), ["store", "info", str(store_path), "--json"])
    assert r.exit_code == 0
    info = json.loads(r.output)
    (scene,) = info["scenes"]
    (view,) = scene["views"]
    assert (scene["name"], view["name"], view["width"], view["height"]) == ("s", "v", 80, 48)
    groups = {g["name"]: g for g in view["groups"]}
    assert {k: groups["g"][k] for k in ("emission", "dtype", "complete")} == \
        {"emission": "flat", "dtype": "float16", "complete": True}
    assert groups["off"]["empty"] and groups["g"]["bytes"] > 0
    assert info["registries"]["sensors"] == ["cam-1"]
    r = CliRunner().invoke(_app(), ["store", "info", str(store_path)])
    assert r.exit_code == 0 and "float16" in r.output and "sensors: 1" in r.output


def test_newer_schema_versions_are_refused(store_path):
    _edit(store_path / CUBE / "zarr.json", lambda a: a["illumix_cube"].update(schema_version=2))
    st = CubeStore.open(store_path, mode="r")
    with pytest.raises(StoreError, match=r"scenes/s/v/cubes/g has schema version 2, newer .* upgrade illumix"):
        st.read_cube("s", "v", "g")
    assert any("schema version 2" in p for p in _problems(store_path))
    _edit(store_path / "zarr.json", lambda a: a["illumix_store"].update(schema_version=9))
    with pytest.raises(StoreError, match="schema version 9"):
        CubeStore.open(store_path, mode="r")


@pytest.mark.parametrize("node,key,call", [
    (CUBE, ("illumix_cube", "stats"), lambda st: st.cube_meta("s", "v", "g")),
    (CUBE, ("illumix_cube", "grid"), lambda st: st.read_cube("s", "v", "g")),
    ("scenes/s/v", ("illumix_view", "width"), lambda st: st.view_meta("s", "v")),
])
def test_missing_attribute_names_the_node(store_path, node, key, call):
    _edit(store_path / node / "zarr.json", lambda a: a[key[0]].pop(key[1]))
    with pytest.raises(StoreError, match=rf"missing attribute '{key[1]}' in .*{node}"):
        call(CubeStore.open(store_path, mode="r"))
    assert any(node in p and key[1] in p for p in _problems(store_path))


def test_corrupt_chunk_is_named_and_verify_fails_with_exit_1(store_path):
    chunk = store_path / CUBE / "data" / "c" / "1" / "0" / "0"
    chunk.write_bytes(b"\x00garbage" * 10)
    st = CubeStore.open(store_path, mode="r")
    with pytest.raises(StoreError, match=r"is damaged .*scenes/s/v/cubes/g/data"):
        st.read_cube("s", "v", "g")
    assert st.read_cube("s", "v", "g", crop=(40, 0, 10, 10)).shape == (10, 10, NB)  # other chunks fine
    assert any(p.startswith(CUBE) for p in _problems(store_path))
    r = CliRunner().invoke(_app(), ["store", "verify", str(store_path)])
    assert r.exit_code == 1 and "PROBLEM" in r.output and CUBE in r.output


def test_missing_chunk_is_detected_not_read_as_zeros(store_path):
    (store_path / CUBE / "data" / "c" / "0" / "1" / "0").unlink()
    st = CubeStore.open(store_path, mode="r")
    with pytest.raises(StoreError, match=r"missing or corrupt chunks in .*cubes/g/data"):
        st.read_cube("s", "v", "g", crop=(33, 0, 4, 4))
    assert st.read_cube("s", "v", "g", crop=(0, 0, 32, 32)).shape == (32, 32, NB)
    assert any("1 of 6 chunks missing" in p for p in _problems(store_path))


def test_stats_mismatch_and_corrupt_registry_entry_are_problems(store_path):
    _edit(store_path / CUBE / "zarr.json", lambda a: a["illumix_cube"]["stats"]["max"].__setitem__(3, 123.0))
    entry = store_path / "_registry" / "sensors" / "cam-1" / "zarr.json"
    _edit(entry, lambda a: a["illumix_registry"].update(data_b64="AAAA"))
    probs = _problems(store_path)
    assert any("decoded max of band 3" in p for p in probs)
    assert any("_registry/sensors/cam-1" in p and "SHA-256" in p for p in probs)


def test_cube_meta_validation():
    with pytest.raises(ValidationError, match="emission has 3 values"):
        CubeMeta(grid=SpectralGrid(), emission=[1, 2, 3])
    with pytest.raises(ValidationError, match="non-negative"):
        CubeMeta(grid=SpectralGrid(400, 410, 5), emission=[1, -1, 1])
    with pytest.raises(ValidationError, match="newer"):
        CubeMeta(grid=SpectralGrid(), schema_version=2)
    with pytest.raises(ValidationError, match="grid"):
        CubeMeta(grid={"start": 700, "end": 400, "step": 5})
    m = CubeMeta(grid=SpectralGrid(400, 410, 5), emission=np.array([0.0, 1.0, 2.0]))
    assert m.n_bands == 3 and m.grid == {"start": 400.0, "end": 410.0, "step": 5.0}


def test_cli_missing_store_is_one_line_exit_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "illumix.cli", "store", "info", str(tmp_path / "nope")],
                       capture_output=True, text=True, cwd=REPO, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("illumix: error: no illumix store at")
