"""Name validation for scenes, views, light groups, AOVs and registry entries.

A name becomes a directory or object-key component, so it must not be able to escape its parent:
no path separators, no ``..``, no leading dot (reserved for temporary files), a bounded length and
a conservative character set that is safe on every filesystem and in URLs.
"""

from __future__ import annotations

import re

from illumix.store.errors import StoreError

MAX_NAME_LEN = 128
#: Letters, digits, ``_ - . +``; must start with a letter or digit.
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+\-]*")
_FMT_RE = re.compile(r"[a-z0-9]{1,16}")
#: ``zarr.json`` is zarr's metadata file; ``*.partial`` are zarr's temporary files.
_RESERVED = {"zarr.json"}


def check_name(name: object, kind: str) -> str:
    """Return ``name`` if it is a safe store name for a ``kind`` (scene, view, group, …), else raise.

    Rules: a ``str`` of 1…128 characters from ``[A-Za-z0-9_.+-]``, starting with a letter or digit,
    without ``..``, not ``zarr.json`` and not ending in ``.partial``.
    """
    if not isinstance(name, str):
        raise StoreError(f"{kind} name must be a string, got {type(name).__name__}")
    if not name:
        raise StoreError(f"{kind} name is empty; give a name like 'kitchen-07'")
    if len(name) > MAX_NAME_LEN:
        raise StoreError(f"{kind} name {name[:32]!r}… is {len(name)} characters; the limit is {MAX_NAME_LEN}")
    if "/" in name or "\\" in name:
        raise StoreError(f"{kind} name {name!r} contains a path separator; use letters, digits, _ - . +")
    if ".." in name:
        raise StoreError(f"{kind} name {name!r} contains '..'; use letters, digits, _ - . +")
    if not _NAME_RE.fullmatch(name):
        bad = sorted({c for c in name if not re.fullmatch(r"[A-Za-z0-9_.+\-]", c)})
        why = f"characters {''.join(bad)!r} are not allowed" if bad else "it must start with a letter or digit"
        raise StoreError(f"invalid {kind} name {name!r}: {why}; use letters, digits, _ - . +")
    if name.lower() in _RESERVED or name.lower().endswith(".partial"):
        raise StoreError(f"{kind} name {name!r} is reserved by the store; choose another name")
    return name


def check_fmt(fmt: object) -> str:
    """A registry payload format tag: 1…16 lowercase letters/digits (``"csv"``, ``"json"``)."""
    if not isinstance(fmt, str) or not _FMT_RE.fullmatch(fmt):
        raise StoreError(f"invalid format tag {fmt!r}: use 1-16 lowercase letters or digits, e.g. 'csv' or 'json'")
    return fmt
