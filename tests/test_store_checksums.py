"""Checksums (store.checksums): every flipped byte is found by `store verify` (exit 1, naming the node)
and never read back as data; leftovers of interrupted writes are reported and `--repair` removes them."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import typer
from store_testutil import add_view, cube, meta, new_store
from typer.testing import CliRunner

from illumix import cmd_store
from illumix.store import CubeStore, StoreError
from illumix.store.report import verify

CUBE = "scenes/s/v/cubes/g"


def _app() -> typer.Typer:
    app = typer.Typer()
    cmd_store.register(app)
    app.command("noop", hidden=True)(lambda: None)
    return app


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("pristine") / "st"
    st = new_store(root)
    rng = np.random.default_rng(0)
    add_view(st, aovs={"depth": rng.random((48, 80)), "mask": rng.random((48, 80)) > 0.5})
    st.write_cube("s", "v", "g", cube(), meta(emission_name="flat"))
    st.mark_empty("s", "v", "off", meta())
    st.registry("sensors").put("cam-1", b"wavelength,r,g,b\n400,0.1,0.2,0.3\n", "csv")
    return root


@pytest.fixture
def store_path(pristine, tmp_path) -> Path:
    return Path(shutil.copytree(pristine, tmp_path / "st"))


def _flip(path: Path, offset: int, n: int = 1, xor: int = 0x5A) -> None:
    data = bytearray(path.read_bytes())
    for i in range(offset, min(offset + n, len(data))):
        data[i] ^= xor
    path.write_bytes(bytes(data))


def _reads(root: Path) -> dict:
    """Everything the store serves through its API (None where a read is refused)."""
    out = {}
    try:
        st = CubeStore.open(root, mode="r")
    except StoreError:
        st = None  # nothing is served
    for name, call in (("cube", lambda: st.read_cube("s", "v", "g")),
                       ("illum", lambda: st.read_cube("s", "v", "g", kind="illumination")),
                       ("depth", lambda: st.read_aov("s", "v", "depth")),
                       ("mask", lambda: st.read_aov("s", "v", "mask")),
                       ("view", lambda: st.view_meta("s", "v").model_dump()),
                       ("groups", lambda: st.groups("s", "v")),
                       ("meta", lambda: st.cube_meta("s", "v", "g").model_dump()),
                       ("sensor", lambda: st.registry("sensors").get("cam-1"))):
        try:
            out[name] = call()
        except Exception:  # noqa: BLE001 - any refusal counts as "not served"
            out[name] = None
    return out


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a == b


def test_a_clean_store_has_checksums_for_every_file(store_path):
    rep = verify(CubeStore.open(store_path, mode="r"))
    assert rep["ok"], rep["problems"]
    files = [p for p in store_path.rglob("*") if p.is_file() and "_checksums" not in p.parts]
    n_group = sum(1 for p in files if p.name == "zarr.json" and p.read_bytes() ==
                  b'{"zarr_format":3,"node_type":"group","attributes":{}}')
    assert rep["checked"]["files_checksummed"] == len(files) - n_group  # empty groups: checked by content
    assert not [n for n in rep["notes"] if "no checksums" in n["what"]]


@pytest.mark.parametrize("target", [f"{CUBE}/data/c/0/0/0", "scenes/s/v/aov/depth/c/0/0"])
def test_sixteen_flipped_bytes_in_a_chunk_are_found_and_not_served(store_path, target):
    """The audit's case: 16 bytes flipped mid-chunk. verify: exit 1 naming the node; reading it: an
    error naming the damage, not the altered values; the store's other nodes are still served."""
    path = store_path / target
    _flip(path, len(path.read_bytes()) // 2, 16)
    r = CliRunner().invoke(_app(), ["store", "verify", str(store_path)])
    assert r.exit_code == 1 and target in r.output and "checksum" in r.output
    st = CubeStore.open(store_path, mode="r")
    read = (lambda: st.read_cube("s", "v", "g")) if "cubes" in target else (lambda: st.read_aov("s", "v", "depth"))
    with pytest.raises(StoreError, match="CRC-32C"):
        read()
    assert st.read_aov("s", "v", "mask").shape == (48, 80)


def test_an_altered_metadata_value_that_still_parses_is_refused(store_path):
    doc = store_path / CUBE / "zarr.json"
    text = doc.read_text()
    assert '"dtype":"float16"' in text
    doc.write_text(text.replace('"dtype":"float16"', '"dtype":"float32"', 1))  # valid, and a different value
    st = CubeStore.open(store_path, mode="r")
    with pytest.raises(StoreError, match="fails its checksum"):
        st.cube_meta("s", "v", "g")
    assert any(p["where"] == f"{CUBE}/zarr.json" for p in verify(st)["problems"])


def test_a_damaged_manifest_and_an_unlisted_file_are_problems(store_path):
    _flip(store_path / CUBE / "_checksums" / "zarr.json", 40)
    (store_path / "scenes/s/v/aov/depth/c/9").mkdir(parents=True)
    (store_path / "scenes/s/v/aov/depth/c/9/9").write_bytes(b"stray")
    where = [p["where"] for p in verify(CubeStore.open(store_path, mode="r"))["problems"]]
    assert CUBE in where and "scenes/s/v/aov/depth/c/9/9" in where


def test_partial_leftovers_are_noted_and_repair_removes_orphans(store_path):
    dead = store_path / "scenes/s/v" / "zarr.json.999999999.0123abcd.partial"  # no such pid
    dead.write_bytes(b'{"half')
    alive = store_path / "scenes/s/v" / f"zarr.json.{os.getpid()}.4567cdef.partial"  # this process: alive
    alive.write_bytes(b'{"half')
    staged = store_path / "_registry/sensors/.cam-2.999999998.89abcdef.partial"  # a killed upload's folder
    staged.mkdir()
    (staged / "zarr.json").write_bytes(b'{"half')
    rep = verify(CubeStore.open(store_path, mode="r"))
    assert rep["ok"] and sum("interrupted write" in n["what"] for n in rep["notes"]) == 3
    r = CliRunner().invoke(_app(), ["store", "verify", str(store_path), "--repair", "--json"])
    assert r.exit_code == 0, r.output
    assert sorted(json.loads(r.output)["repaired"]) == sorted(str(p.relative_to(store_path)) for p in (dead, staged))
    assert not dead.exists() and not staged.exists() and alive.exists()


def test_every_random_byte_flip_is_found_and_none_is_served(store_path, tmp_path):
    """A bounded corruption sweep (bench/corruption.py runs a longer one): each trial flips one random
    byte of one random file (chunks and metadata alike) of a fresh copy; verify must report a problem,
    and whatever is still served must equal the undamaged store's."""
    rng = np.random.default_rng(7)
    clean = _reads(store_path)
    files = sorted(p.relative_to(store_path) for p in store_path.rglob("*") if p.is_file())
    for trial in range(40):
        root = Path(shutil.copytree(store_path, tmp_path / f"t{trial}"))
        rel = files[rng.integers(len(files))]
        size = (root / rel).stat().st_size
        _flip(root / rel, int(rng.integers(size)), 1, int(rng.integers(1, 256)))
        try:
            rep = verify(CubeStore.open(root, mode="r"))
        except StoreError as exc:  # the root document itself: the store does not open, naming it
            assert "zarr.json" in str(exc), str(exc)
        else:
            assert not rep["ok"], f"flip in {rel} not found"
        got = _reads(root)
        for k, v in got.items():
            assert v is None or _same(v, clean[k]), f"flip in {rel}: {k} served altered"
        shutil.rmtree(root)


def test_a_document_once_verified_is_not_checked_against_its_manifest_again(monkeypatch):
    """Object stores re-read a cube's document on every request: its manifest is read once, not with
    every read of the same bytes; altered bytes are checked (and refused) again."""
    from illumix.store import checksums

    st = new_store("memory://checksum-cache/st")
    add_view(st)
    st.write_cube("s", "v", "g", cube(), meta(emission_name="flat"))
    reads = []
    real = checksums.read_manifest
    monkeypatch.setattr(checksums, "read_manifest", lambda b, node: reads.append(node) or real(b, node))
    for _ in range(3):
        st.cube_meta("s", "v", "g")
    assert reads.count(CUBE) == 1
    raw = st.backend.read_bytes(f"{CUBE}/zarr.json")
    st.backend.write_bytes(f"{CUBE}/zarr.json", raw.replace(b'"dtype":"float16"', b'"dtype":"float32"', 1))
    monkeypatch.setattr(checksums, "RECHECK_S", 0.0)
    with pytest.raises(StoreError, match="fails its checksum"):
        st.cube_meta("s", "v", "g")


def test_min_age_goes_with_repair(store_path, capsys):
    from cli_testutil import run_cli

    code, out, err = run_cli(capsys, "store", "verify", str(store_path), "--min-age", "5")
    assert code == 2 and out == "" and err.strip().count("\n") == 0 and "--min-age goes with --repair" in err
