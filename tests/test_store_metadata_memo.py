"""The local backend remembers parsed metadata files while they are unchanged (a service reads the
same few on every request): every way a file can change is still seen at once."""

from __future__ import annotations

import os

import pytest
from store_testutil import add_view, cube, meta, new_store

from store import CubeStore, StoreKeyError


def test_an_unchanged_metadata_file_is_parsed_once(tmp_path):
    st = new_store(tmp_path / "s")
    add_view(st)
    key = "scenes/s/v/zarr.json"
    assert st.backend.read_json(key) is st.backend.read_json(key)


def test_a_reader_sees_a_cube_overwritten_deleted_and_written_again(tmp_path):
    st = new_store(tmp_path / "s")
    add_view(st)
    st.write_cube("s", "v", "g", cube(), meta(emission_name="first"))
    reader = CubeStore.open(tmp_path / "s", mode="r")  # a service's long-lived handle
    assert reader.cube_meta("s", "v", "g").emission_name == "first"
    st.write_cube("s", "v", "g", cube(seed=1), meta(emission_name="second"), overwrite=True)
    assert reader.cube_meta("s", "v", "g").emission_name == "second"
    st.delete("s", "v", "g")
    assert reader.groups("s", "v") == []
    with pytest.raises(StoreKeyError):
        reader.cube_meta("s", "v", "g")
    st.write_cube("s", "v", "g", cube(), meta(emission_name="third"))
    assert reader.cube_meta("s", "v", "g").emission_name == "third"
    assert reader.groups("s", "v") == ["g"]


def test_a_same_size_rewrite_in_the_same_nanosecond_is_seen(tmp_path):
    """Every metadata write replaces the file (a new inode), so even a rewrite of equal size with
    the old modification time is read again."""
    st = new_store(tmp_path / "s")
    add_view(st)
    b = st.backend
    b.write_bytes("x/zarr.json", b'{"a": 1}')
    assert b.read_json("x/zarr.json") == {"a": 1}
    old = os.stat(tmp_path / "s" / "x" / "zarr.json")
    b.write_bytes("x/zarr.json", b'{"a": 2}')
    os.utime(tmp_path / "s" / "x" / "zarr.json", ns=(old.st_atime_ns, old.st_mtime_ns))
    assert b.read_json("x/zarr.json") == {"a": 2}
    os.remove(tmp_path / "s" / "x" / "zarr.json")
    assert b.read_json("x/zarr.json") is None
