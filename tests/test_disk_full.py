"""Issue 36 item 5: a full, read-only or failing disk in every writer — ``illumix render``, ``illumix
dataset``, ``illumix export``, ``evaluate --out`` and the store's upload registries — ends in one line
(exit 2; HTTP 507 from the service) naming what could not be written and how to go on, leaves nothing
half-written, and a rerun once there is space completes. A delete needs no new space: it works on a
full disk, so space can be freed through the API.

The disk is not really filled: :class:`FullDisk` makes every Python-level write under one folder fail
with ``OSError(errno)`` once a byte budget is spent (the write that crosses it writes what fits
first, as a real disk does), and directories stop being created there too. The writers all write
through Python files (zarr's local store, numpy, the journal, the encoders' bytes); only C libraries
that open files themselves (OpenEXR) are not covered by it.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import threading
from pathlib import Path

import pytest
from cli_testutil import run_cli
from test_cli_spectra import assert_one_line_error

needs_mitsuba = pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                                   reason="rendering needs the optional extra illumix[render]")
TOKEN = "s3cret"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


class FullDisk:
    """Writes under ``root`` fail with ``OSError(err)`` once ``budget`` bytes are written (module docstring);
    ``written`` counts what was. ``free()`` ends it (the disk was cleaned up)."""

    def __init__(self, monkeypatch, root, budget: float = 0, err: int = errno.ENOSPC) -> None:
        self.root, self.left, self.err, self.written = os.path.abspath(root), budget, err, 0
        self.lock = threading.Lock()
        real_open, real_mkdir = io.open, os.mkdir

        def fake_open(file, mode="r", *args, **kw):
            f = real_open(file, mode, *args, **kw)
            return _Proxy(f, self) if any(c in mode for c in "wax+") and self.ours(file) else f

        def fake_mkdir(path, *args, **kw):
            if self.ours(path) and self.left <= 0:
                raise OSError(self.err, os.strerror(self.err), str(path))
            return real_mkdir(path, *args, **kw)

        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)
        monkeypatch.setattr(os, "mkdir", fake_mkdir)

    def ours(self, path) -> bool:
        if not isinstance(path, (str, os.PathLike)):
            return False
        path = os.path.abspath(path)
        return path == self.root or path.startswith(self.root + os.sep)

    def take(self, n: int) -> int:
        with self.lock:
            granted = int(max(0, min(n, self.left)))
            self.left -= granted
            self.written += granted
            return granted

    def fail(self) -> OSError:
        return OSError(self.err, os.strerror(self.err))

    def free(self) -> None:
        self.left = float("inf")


class _Proxy:
    """A file whose writes draw on a :class:`FullDisk`'s budget."""

    def __init__(self, f, disk: FullDisk) -> None:
        self._f, self._disk = f, disk

    def write(self, data):
        raw = data.encode() if isinstance(data, str) else memoryview(data).cast("B")
        granted = self._disk.take(len(raw))
        if granted < len(raw):
            if granted:
                self._f.write(data[:granted] if isinstance(data, str) else raw[:granted])
            raise self._disk.fail()
        return self._f.write(data)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._f.close()

    def __iter__(self):
        return iter(self._f)

    def __getattr__(self, name):
        return getattr(self._f, name)


def leftovers(root: Path) -> list[str]:
    """Temporary files of interrupted writes under ``root``."""
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")
                  if p.name.endswith(".partial") or ".illumix-tmp" in p.name or p.name.endswith(".tmp"))


def disk_line(err: str, needle: str) -> str:
    """The one error line, checked to say what happened and how to go on."""
    line = err.strip("\n")
    assert "\n" not in line and "Traceback" not in err and line.startswith("illumix: error: could not write "), err
    assert needle in line, line
    return line


# -- export ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def export_store(tmp_path_factory):
    pytest.importorskip("rawpy")
    from export_testutil import build_export_store

    return build_export_store(tmp_path_factory.mktemp("full") / "store")


EXPORT = ["--size", "32x24", "--count", "3", "--json"]


@pytest.mark.parametrize("fmt", ["lsmi", "dng"])
def test_export_on_a_full_disk_is_one_line_and_a_rerun_completes(export_store, tmp_path, capsys, monkeypatch, fmt):
    code, _, err = run_cli(capsys, "export", export_store, str(tmp_path / "whole"), "--format", fmt, *EXPORT)
    assert code == 0, err
    total = sum(p.stat().st_size for p in (tmp_path / "whole").rglob("*") if p.is_file())
    out = tmp_path / "o"
    disk = FullDisk(monkeypatch, out, budget=total // 2)
    code, stdout, err = run_cli(capsys, "export", export_store, str(out), "--format", fmt, *EXPORT)
    assert code == 2 and stdout == ""
    line = disk_line(err, "No space left on device; free space on that disk or choose another OUT folder, then run "
                          "the same command again: it resumes")
    assert f"could not write {out}{os.sep}" in line
    assert not leftovers(out) and not (out / "manifest.json").exists()
    monkeypatch.undo()  # the disk was cleaned up
    code, _, err = run_cli(capsys, "export", export_store, str(out), "--format", fmt, *EXPORT)
    assert code == 0, err
    whole = json.loads((tmp_path / "whole" / "manifest.json").read_text())["files"]
    again = json.loads((out / "manifest.json").read_text())["files"]
    assert {k: v for k, v in whole.items() if k != "README.md"} == {k: v for k, v in again.items() if k != "README.md"}
    assert disk.written > 0


@pytest.mark.parametrize("err_no, fix", [
    (errno.EIO, "check the disk or mount (dmesg) or choose another OUT folder"),
    (errno.EROFS, "choose another OUT folder on a writable disk"),
    (errno.EACCES, "make it writable for you or choose another OUT folder"),
    (errno.EDQUOT, "free space within your disk quota"),
])
def test_export_io_errors_are_one_line(export_store, tmp_path, capsys, monkeypatch, err_no, fix):
    out = tmp_path / "o"
    FullDisk(monkeypatch, out, budget=2000, err=err_no)
    code, _, err = run_cli(capsys, "export", export_store, str(out), *EXPORT)
    assert code == 2
    disk_line(err, f"{os.strerror(err_no)}; {fix}")
    assert not leftovers(out)


def test_export_exr_whose_c_library_reports_a_full_disk_is_one_line(export_store, tmp_path, capsys, monkeypatch):
    """OpenEXR writes its files itself and says so in a RuntimeError (as on a real full tmpfs)."""
    pytest.importorskip("OpenEXR")
    from illumix.dataset_export import exr_layout

    calls = []

    def full(path, cube, wavelengths, **kw):
        calls.append(path)
        if len(calls) > 2:
            Path(path).write_bytes(b"half an EXR")
            raise RuntimeError(f'Failed to write pixel data to image file "{path}". No space left on device.')
        return real(path, cube, wavelengths, **kw)

    real = exr_layout.write_spectral_exr
    monkeypatch.setattr(exr_layout, "write_spectral_exr", full)
    out = tmp_path / "o"
    code, _, err = run_cli(capsys, "export", export_store, str(out), "--format", "exr", "--size", "16x12", "--json")
    assert code == 2
    disk_line(err, "No space left on device; free space on that disk or choose another OUT folder")
    assert not leftovers(out) and len([p for p in out.rglob("*.exr")]) == 2
    monkeypatch.undo()
    code, _, err = run_cli(capsys, "export", export_store, str(out), "--format", "exr", "--size", "16x12", "--json")
    assert code == 0, err


def test_a_journal_line_cut_by_a_full_disk_is_not_glued_to_the_next(tmp_path, monkeypatch):
    from illumix.dataset_export.errors import ExportWriteError
    from illumix.dataset_export.journal import JOURNAL, Journal

    Journal(tmp_path, {"a": 1})
    disk = FullDisk(monkeypatch, tmp_path, budget=8)
    with pytest.raises(ExportWriteError) as info:
        Journal(tmp_path, {"a": 1}).write_bytes("f.txt", b"1234")  # the file fits, its journal line does not
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / JOURNAL)
    disk.free()
    Journal(tmp_path, {"a": 1}).write_bytes("g.txt", b"5678")
    j = Journal(tmp_path, {"a": 1})
    assert "g.txt" in j.files and j.complete("g.txt") and "f.txt" not in j.files  # f.txt: written again by a rerun


# -- the service's registries ----------------------------------------------------------------------
@pytest.fixture()
def service(tmp_path):
    """A fresh store (no ``_trash`` yet: the first delete must not need one) and its service."""
    import synthetic_store
    from fastapi.testclient import TestClient
    from illumix.service.app import create_app
    from illumix.store import CubeStore

    path = tmp_path / "store"
    synthetic_store.build(path)
    with TestClient(create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=64)) as c:
        yield path, c


def _csv(scale: float = 1.0) -> str:
    import colour

    sd = colour.SDS_ILLUMINANTS["D65"]
    return "\n".join(f"{w:g},{v * scale:.6g}" for w, v in zip(sd.wavelengths, sd.values))


def _sensor_csv() -> str:
    import colour

    cam = colour.MSDS_CAMERA_SENSITIVITIES["Nikon 5100 (NPL)"]
    return "\n".join(f"{w:g}," + ",".join(f"{v:.6g}" for v in row) for w, row in zip(cam.wavelengths, cam.values))


@pytest.mark.parametrize("err_no, code", [(errno.ENOSPC, "store_full"), (errno.EDQUOT, "store_full"),
                                          (errno.EROFS, "store_unwritable"), (errno.EIO, "store_unwritable"),
                                          (errno.EACCES, "store_unwritable")])
def test_uploads_on_a_refusing_disk_are_507_and_deletes_still_work(service, monkeypatch, err_no, code):
    path, client = service
    for kind, name, body in (("illuminants", "kept", _csv()), ("sensors", "cam", _sensor_csv())):
        r = client.post(f"/{kind}", data={"name": name}, files={"file": (f"{name}.csv", body)}, headers=AUTH)
        assert r.status_code == 201, r.text
    disk = FullDisk(monkeypatch, path, budget=0, err=err_no)
    for kind, body, overwrite in (("illuminants", _csv(), False), ("illuminants", _csv(2.0), True),
                                  ("sensors", _sensor_csv(), False)):
        name = "kept" if overwrite else "new"
        r = client.post(f"/{kind}", data={"name": name, "overwrite": str(overwrite).lower()},
                        files={"file": (f"{name}.csv", body)}, headers=AUTH)
        assert r.status_code == 507, r.text
        body = r.json()
        assert body["code"] == code and os.strerror(err_no) in body["detail"] and "nothing was written" in body["detail"]
        assert "\n" not in body["detail"]
    assert client.get("/illuminants").json()["uploaded"] == ["kept"]  # the overwrite left the old entry whole
    assert not leftovers(path) and not [p for p in (path / "_registry").rglob(".*")]
    # deleting needs no space: it works while every write fails, and frees the space
    for kind, name in (("illuminants", "kept"), ("sensors", "cam")):
        r = client.delete(f"/{kind}/{name}", headers=AUTH)
        assert r.status_code == 200, r.text
        assert not (path / "_registry" / kind / name).exists()
    assert client.get("/illuminants").json()["uploaded"] == [] and "cam" not in client.get("/sensors").json()["uploaded"]
    assert disk.written == 0 and not (path / "_trash").exists()
    disk.free()
    r = client.post("/illuminants", data={"name": "kept"}, files={"file": ("k.csv", _csv())}, headers=AUTH)
    assert r.status_code == 201, r.text


def test_registry_put_and_delete_leave_nothing_behind(tmp_path, monkeypatch):
    from illumix.store import CubeStore, StoreWriteError

    st = CubeStore.open(str(tmp_path / "s"), mode="a")
    reg = st.registry("illuminants")
    reg.put("a", _csv().encode(), "csv")
    with monkeypatch.context() as m:
        disk = FullDisk(m, tmp_path / "s", budget=float("inf"))
        reg.put("b", _csv(3.0).encode(), "csv")
        reg.delete("b")
    need = disk.written  # the document and its manifest
    for budget in (*range(0, need, max(1, need // 7)), need - 1):  # cut in the document, in its manifest
        with monkeypatch.context() as m:
            FullDisk(m, tmp_path / "s", budget=budget)
            for name, overwrite in (("b", False), ("a", True)):
                try:
                    reg.put(name, _csv(3.0).encode(), "csv", overwrite=overwrite)
                except StoreWriteError as exc:
                    assert exc.errno == errno.ENOSPC and "nothing was written" in str(exc)
        assert reg.get("a")[0] in (_csv().encode(), _csv(3.0).encode())  # old or new, never half
        assert not [p for p in (tmp_path / "s" / "_registry").rglob(".*")] and not leftovers(tmp_path / "s")
        if "b" in reg.names():
            assert reg.get("b")[0] == _csv(3.0).encode()
            reg.delete("b")


def test_a_put_killed_mid_way_is_finished_by_the_next(tmp_path):
    """kill -9 between the renames of an overwrite: the entry renamed aside comes back; a staged one goes."""
    import subprocess
    import sys

    from illumix.store import CubeStore

    st = CubeStore.open(str(tmp_path / "s"), mode="a")
    reg = st.registry("illuminants")
    reg.put("a", _csv().encode(), "csv")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True).stdout.strip()
    folder = tmp_path / "s" / "_registry" / "illuminants"
    os.rename(folder / "a", folder / f".a.{dead}.{'0' * 32}.old")
    (folder / f".b.{dead}.{'1' * 32}.partial").mkdir()
    (folder / f".c.{os.getpid()}.{'2' * 32}.partial").mkdir()  # a live writer's: left alone
    assert reg.names() == []
    reg.put("d", _csv(2.0).encode(), "csv")
    assert reg.names() == ["a", "d"] and reg.get("a")[0] == _csv().encode()
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == [f".c.{os.getpid()}.{'2' * 32}.partial"]


# -- render and dataset ----------------------------------------------------------------------------
def _complete_only(store: Path) -> int:
    """The store holds complete cubes only (no incomplete node, nothing staged); returns how many."""
    from illumix.store import CubeStore

    st = CubeStore.open(str(store), mode="r")
    n = 0
    for scene in st.scenes():
        for view in st.views(scene):
            assert st.groups(scene, view, include_incomplete=True) == st.groups(scene, view)
            n += len(st.groups(scene, view))
    assert not st.pending_writes() and not leftovers(store)
    return n


@needs_mitsuba
def test_render_on_a_full_disk_is_one_line_and_a_rerun_completes(tmp_path, capsys, monkeypatch):
    from test_render_cli import tiny_scene_file

    args = ["render", tiny_scene_file(tmp_path), "--spp", "4", "--json", "--store"]
    with monkeypatch.context() as m:
        disk = FullDisk(m, tmp_path / "whole", budget=float("inf"))
        code, out, err = run_cli(capsys, *args, str(tmp_path / "whole"))
    assert code == 0, err
    jobs = json.loads(out.strip().splitlines()[-1])["rendered"]
    store = tmp_path / "st"
    with monkeypatch.context() as m:
        FullDisk(m, store, budget=disk.written // 2)
        code, out, err = run_cli(capsys, *args, str(store))
    assert code == 2 and out == ""
    line = disk_line(err, "No space left on device; free space on that disk or render into another --store, then "
                          "run the same command again: the ")
    assert f"into the store {store}" in line and "job(s) finished are kept and it renders the rest" in line
    kept = _complete_only(store)
    code, out, err = run_cli(capsys, *args, str(store))
    assert code == 0, err
    again = json.loads(out.strip().splitlines()[-1])["rendered"]
    assert 0 < len(again) < len(jobs) and _complete_only(store) == 4 and kept < 4


@needs_mitsuba
@pytest.mark.parametrize("err_no", [errno.ENOSPC, errno.EROFS, errno.EIO, errno.EACCES])
def test_render_into_a_store_the_disk_refuses_is_one_line(tmp_path, capsys, monkeypatch, err_no):
    from test_render_cli import tiny_scene_file

    cfg = tiny_scene_file(tmp_path)
    FullDisk(monkeypatch, tmp_path / "st", budget=0, err=err_no)
    code, out, err = run_cli(capsys, "render", cfg, "--spp", "4", "--store", str(tmp_path / "st"), "--json")
    assert code == 2 and out == ""
    disk_line(err, f"into the store {tmp_path / 'st'}: {os.strerror(err_no)}; ")
    assert "render into another --store" in err and "run the same command again: it resumes" in err


@needs_mitsuba
def test_dataset_stops_at_a_full_disk_with_one_line_and_resumes(tmp_path, capsys, monkeypatch):
    from test_dataset import RENDER, write_config
    from test_render_cli import tiny_scene_file

    cfg = write_config(tmp_path, {"name": "d", "scenes": [tiny_scene_file(tmp_path)], "render": dict(RENDER)})
    with monkeypatch.context() as m:
        disk = FullDisk(m, tmp_path / "whole", budget=float("inf"))
        code, _, err = run_cli(capsys, "dataset", cfg, "--store", str(tmp_path / "whole"), "--json")
    assert code == 0, err
    store = tmp_path / "st"
    with monkeypatch.context() as m:
        FullDisk(m, store, budget=disk.written // 2)
        code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(store), "--json")
    assert code == 2 and out == ""  # not "N jobs failed" and exit 1: every later job would fail alike
    disk_line(err, "No space left on device; free space on that disk or render into another --store")
    kept = _complete_only(store)
    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(store), "--json")
    assert code == 0, err
    s = json.loads(out.strip().splitlines()[-1])
    assert s["cubes_skipped"] == kept and s["failed"] == [] and _complete_only(store) == 4


def test_dataset_room_cache_on_a_full_disk_is_one_line(tmp_path, capsys, monkeypatch):
    from illumix.store import CubeStore
    from test_dataset import tiny, write_config

    cfg = write_config(tmp_path, tiny(generated={"count": 1, "seed": 3,
                                                 "generator": {"probe": False, "views": [1, 1], "resolution": [16, 12]}}))
    CubeStore.open(str(tmp_path / "st"), mode="a")
    FullDisk(monkeypatch, tmp_path / "st", budget=0)
    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(tmp_path / "st"))
    assert code == 2 and out == ""
    disk_line(err, "No space left on device; free space on that disk or give another --scenes-dir")
    assert not leftovers(tmp_path / "st") and not list((tmp_path / "st").rglob("room-*.yaml"))


# -- evaluate --out and the command line's last resort ------------------------------------------------
def test_evaluate_out_on_a_full_disk_is_one_line(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib")
    from evaluate_testutil import make_store

    store = str(make_store(tmp_path / "store"))
    out = tmp_path / "out"
    FullDisk(monkeypatch, out, budget=300)
    code, _, err = run_cli(capsys, "evaluate", store, "--methods", "GW", "--pairs", "A,D65", "--out", str(out))
    assert code == 2
    disk_line(err, "No space left on device; free space on that disk or give another --out, then run the evaluation again")
    assert not leftovers(out)


def test_a_storage_error_no_command_words_is_still_one_line(capsys, monkeypatch):
    from illumix.retarget import sensors

    def failing(*args, **kw):
        raise OSError(errno.EIO, os.strerror(errno.EIO), "/mnt/cams/x.json")

    monkeypatch.setattr(sensors, "get_sensor", failing)
    line = assert_one_line_error(*run_cli(capsys, "whitepoint", "--sensor", "x", "--illuminant", "D65"))
    assert line == ("illumix: error: /mnt/cams/x.json: Input/output error; check the disk or mount (dmesg) or use "
                    "another location, then run the command again")


def test_the_service_answers_a_bare_full_disk_oserror_with_507():
    """A write some route lets through unwrapped: still the disk's 507, not a 500 (other OSErrors stay 500)."""
    from fastapi import FastAPI
    from fastapi.testclient import TestClient
    from illumix.service.errors import install

    app = FastAPI()
    install(app)

    @app.get("/full")
    def full():
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    @app.get("/other")
    def other():
        raise OSError(errno.EIO, os.strerror(errno.EIO))  # may be a read: not called the disk's refusal

    c = TestClient(app, raise_server_exceptions=False)
    r = c.get("/full")
    assert r.status_code == 507 and r.json()["code"] == "store_full" and "free space" in r.json()["detail"]
    assert c.get("/other").status_code == 500
