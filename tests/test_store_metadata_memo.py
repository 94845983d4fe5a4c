"""The local backend remembers parsed metadata files while they are unchanged (a service reads the
same few on every request). Every write replaces a file, so a new version has a new inode and mtime;
files written in the last seconds are not remembered, because on a file system with coarse
timestamps a rewrite in the same tick could reuse the inode (git's "racy" rule)."""

from __future__ import annotations

import os
import time

import pytest

from store_testutil import add_view, cube, meta, new_store

from illumix.store import CubeStore, StoreKeyError, backend


def _age(path, seconds: float = 10.0) -> None:
    """Set ``path``'s mtime ``seconds`` into the past (a file written a while ago)."""
    t = time.time_ns() - int(seconds * 1e9)
    os.utime(path, ns=(t, t))


def test_an_old_unchanged_metadata_file_is_parsed_once(tmp_path):
    st = new_store(tmp_path / "s")
    add_view(st)
    key = "scenes/s/v/zarr.json"
    assert st.backend.read_json(key) is not st.backend.read_json(key)  # just written: not remembered
    _age(tmp_path / "s" / key)
    assert st.backend.read_json(key) is st.backend.read_json(key)


def test_a_reader_sees_a_cube_overwritten_deleted_and_written_again(tmp_path):
    st = new_store(tmp_path / "s")
    add_view(st)
    node = tmp_path / "s" / "scenes" / "s" / "v" / "cubes" / "g" / "zarr.json"

    def write(name, **kw):
        st.write_cube("s", "v", "g", cube(), meta(emission_name=name), **kw)
        _age(node, 10 + len(name))  # an old file, each version with its own mtime

    write("first")
    reader = CubeStore.open(tmp_path / "s", mode="r")  # a service's long-lived handle
    assert reader.cube_meta("s", "v", "g").emission_name == "first"
    assert reader.cube_meta("s", "v", "g").emission_name == "first"  # now from the memo
    write("second", overwrite=True)
    assert reader.cube_meta("s", "v", "g").emission_name == "second"
    st.delete("s", "v", "g")
    assert reader.groups("s", "v") == []
    try:
        reader.cube_meta("s", "v", "g")
        raise AssertionError("a deleted cube was read")
    except StoreKeyError:
        pass
    write("third")
    assert reader.cube_meta("s", "v", "g").emission_name == "third"
    assert reader.groups("s", "v") == ["g"]


def test_a_rewrite_in_the_same_timestamp_tick_reusing_the_inode_is_seen(tmp_path):
    """Three writes of equal size: the third may reuse the first's inode (ext4 alternates two), and
    on a coarse clock get the first's mtime. The first was read at once, so it was not remembered."""
    st = new_store(tmp_path / "s")
    b = st.backend
    path = tmp_path / "s" / "x" / "zarr.json"
    b.write_bytes("x/zarr.json", b'{"a": 1}')
    first = os.stat(path)
    assert b.read_json("x/zarr.json") == {"a": 1}
    b.write_bytes("x/zarr.json", b'{"a": 2}')
    b.write_bytes("x/zarr.json", b'{"a": 3}')
    os.utime(path, ns=(first.st_atime_ns, first.st_mtime_ns))  # the coarse clock's same tick
    if os.stat(path).st_ino != first.st_ino:
        pytest.skip("this file system gave the rewrite a new inode: the stamps differ anyway")
    assert b.read_json("x/zarr.json") == {"a": 3}
    os.remove(path)
    assert b.read_json("x/zarr.json") is None


def test_the_memo_is_bounded_in_bytes(tmp_path, monkeypatch):
    monkeypatch.setattr(backend, "JSON_MEMO_BYTES", 1000)
    st = new_store(tmp_path / "s")
    b = st.backend
    data = b'{"pad": "' + b"x" * 90 + b'"}'
    for i in range(20):
        b.write_bytes(f"n{i}/zarr.json", data)
        _age(tmp_path / "s" / f"n{i}" / "zarr.json")
        b.read_json(f"n{i}/zarr.json")
    assert 0 < b._json_bytes <= 1000 and len(b._json_memo) == 1000 // (3 * len(data))
    assert "n19/zarr.json" in b._json_memo and "n0/zarr.json" not in b._json_memo  # oldest reads go first
