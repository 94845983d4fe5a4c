"""User registries (uploaded sensors / illuminants) persisted in the store."""

from __future__ import annotations

import uuid

import pytest
from store_testutil import new_store

from illumix.store import CubeStore, StoreError, StoreKeyError

CSV = b"wavelength,r,g,b\n400,0.1,0.2,0.3\n700,0.3,0.2,0.1\n"


def test_put_get_list_delete_and_survive_reopen(tmp_path):
    st = new_store(tmp_path / "st")
    reg = st.registry("sensors")
    e = reg.put("IMX135", CSV, "csv")
    assert (e.name, e.fmt, e.size) == ("IMX135", "csv", len(CSV)) and len(e.sha256) == 64
    reg.put("cam.v2+x_y-z", b'{"a": 1}', "json")
    st.registry("illuminants").put("lamp-3000K", b"wavelength,value\n400,1\n", "csv")
    re = CubeStore.open(tmp_path / "st", mode="r")  # a restart loses nothing
    assert re.registry("sensors").names() == ["IMX135", "cam.v2+x_y-z"]
    assert re.registry("sensors").get("IMX135") == (CSV, "csv")
    assert re.registry("illuminants").names() == ["lamp-3000K"] and "lamp-3000K" in re.registry("illuminants")
    with pytest.raises(StoreError, match="read-only"):
        re.registry("sensors").put("other", CSV, "csv")
    reg.delete("IMX135")
    assert reg.names() == ["cam.v2+x_y-z"] and "IMX135" not in reg
    with pytest.raises(StoreKeyError, match="no sensor 'IMX135'"):
        reg.get("IMX135")
    with pytest.raises(StoreKeyError):
        reg.delete("IMX135")
    assert not (tmp_path / "st" / "_registry" / "sensors" / "IMX135").exists()


def test_overwrite_protection(tmp_path):
    reg = new_store(tmp_path / "st").registry("sensors")
    reg.put("cam", CSV, "csv")
    with pytest.raises(StoreError, match="already exists.*overwrite=True"):
        reg.put("cam", b"other", "csv")
    assert reg.get("cam") == (CSV, "csv")
    reg.put("cam", b'{"x": 2}', "json", overwrite=True)
    assert reg.get("cam") == (b'{"x": 2}', "json")


@pytest.mark.parametrize("name", ["../x", "a/b", "a\\b", "..", "x..y", ".env", "", "n" * 129, "sp ace", "é", None])
def test_name_validation(tmp_path, name):
    root = tmp_path / "st"
    reg = new_store(root).registry("illuminants")
    with pytest.raises(StoreError):
        reg.put(name, CSV, "csv")
    assert reg.names() == [] and sorted(p.name for p in tmp_path.iterdir()) == ["st"]


def test_size_format_and_kind_limits(tmp_path):
    st = new_store(tmp_path / "st")
    reg = st.registry("sensors", max_bytes=100)
    reg.put("ok", b"x" * 100, "csv")
    with pytest.raises(StoreError, match="101 bytes exceeds the 100-byte limit"):
        reg.put("big", b"x" * 101, "csv")
    with pytest.raises(StoreError, match="empty"):
        reg.put("empty", b"", "csv")
    for fmt in ["CSV", "c/v", "", "x" * 17]:
        with pytest.raises(StoreError, match="format"):
            reg.put("f", CSV, fmt)
    with pytest.raises(StoreError, match="unknown registry"):
        st.registry("scenes")
    assert reg.names() == ["ok"]
    assert st.registry("sensors").max_bytes == 1 << 20  # default limit: 1 MiB


def test_registry_on_fsspec_url():
    st = CubeStore.open(f"memory://illumix-reg-{uuid.uuid4().hex}")
    reg = st.registry("sensors")
    reg.put("cam", CSV, "csv")
    with pytest.raises(StoreError, match="already exists"):
        reg.put("cam", CSV, "csv")
    assert reg.names() == ["cam"] and reg.get("cam") == (CSV, "csv")
    reg.delete("cam")
    assert reg.names() == []
