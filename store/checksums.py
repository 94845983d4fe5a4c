"""Checksums: every byte a store holds can be checked, and a damaged node is found, named and isolated.

Two layers, because they answer two questions at two costs:

* **Chunks carry a CRC-32C** (zarr v3's ``crc32c`` codec, the last codec of every array illumix
  writes, :func:`store.layout.compressors`): zarr checks it whenever a chunk is decoded, so the
  service never serves a flipped byte of a chunk as data — the read fails and that cube answers 503.
* **Every node has a manifest** ``_checksums/zarr.json`` (a zarr group of its own, so any zarr
  reader still opens the store without complaint): the SHA-256 of each file under the node (its
  metadata documents and chunk files), itself sealed by the SHA-256 of its entries. It is written
  with the node (before the node is published) and read by ``illumix store verify`` (every file,
  every byte) and, cheaply, by readers when they first parse a metadata document
  (:func:`check_document`): a document that parses but was altered is refused like an unparsable one.

A node written before checksums existed has no manifest: verify notes it and it is served as before.
Intermediate groups (``scenes/``, ``scenes/<scene>/``, ``…/cubes``, ``…/aov``) hold nothing but their
kind; they are checked against that exact content instead (:data:`EMPTY_GROUP`).
"""

from __future__ import annotations

import hashlib
import json
import os
import threading
import time
from collections import OrderedDict
from typing import TYPE_CHECKING

from illumix.store.backend import EMPTY_GROUP_BYTES
from illumix.store.errors import StoreError

if TYPE_CHECKING:
    from illumix.store.backend import Backend

MANIFEST_NODE = "_checksums"
MANIFEST = f"{MANIFEST_NODE}/zarr.json"
MANIFEST_ATTR = "illumix_checksums"
FORMAT = 1
PARTIAL = ".partial"
#: an intermediate group's document, as illumix writes it (compact, so any flipped byte changes it)
EMPTY_GROUP = {"zarr_format": 3, "node_type": "group", "attributes": {}}
#: a reader that finds a document and its manifest disagree reads both again this many times, this far
#: apart, before calling it damage: a writer replacing a document in place (object stores) writes it
#: and its manifest one after the other
RECHECKS, RECHECK_S = 3, 0.05


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _seal(entries: dict[str, str]) -> str:
    return sha256(json.dumps(entries, sort_keys=True, separators=(",", ":")).encode())


def manifest_bytes(entries: dict[str, str]) -> bytes:
    """The manifest document of ``{relative path: SHA-256}``: a zarr group whose attributes hold it."""
    body = {"format": FORMAT, "files": entries, "sha256": _seal(entries)}
    return json.dumps({"zarr_format": 3, "node_type": "group", "attributes": {MANIFEST_ATTR: body}},
                      sort_keys=True, separators=(",", ":")).encode()


def write_manifest(b: Backend, node: str, files: list[str] | None = None,
                   known: dict[str, bytes] | None = None) -> None:
    """Hash ``files`` (paths relative to ``node``; ``None``: every file under it) and write the node's
    manifest atomically. ``known``: bytes already in hand for some of them (not read back)."""
    known = known or {}
    rels = files if files is not None else [r for r in b.list_files(node) if _counted(r)]
    entries = {}
    for rel in rels:
        data = known.get(rel)
        if data is None:
            data = b.read_bytes(f"{node}/{rel}" if node else rel)
        if data is None:
            raise StoreError(f"{node}/{rel} vanished while its checksum was being written; write the node again")
        entries[rel] = sha256(data)
    b.write_bytes(f"{node}/{MANIFEST}" if node else MANIFEST, manifest_bytes(entries))


def _counted(rel: str) -> bool:
    """Files a node's manifest covers: not the manifest, not a temporary ``.partial`` file."""
    return not rel.startswith(MANIFEST_NODE + "/") and not rel.endswith(PARTIAL)


def read_manifest(b: Backend, node: str) -> dict[str, str] | None:
    """``{relative path: SHA-256}`` of the node's manifest; ``None`` without one; :class:`StoreError`
    naming the node when the manifest itself is damaged."""
    key = f"{node}/{MANIFEST}" if node else MANIFEST
    raw = b.read_bytes(key)
    if raw is None:
        return None
    try:
        doc = json.loads(raw)["attributes"][MANIFEST_ATTR]
        entries = doc["files"]
        ok = doc["format"] == FORMAT and isinstance(entries, dict) and doc["sha256"] == _seal(entries)
    except (ValueError, KeyError, TypeError):
        ok = False
    if not ok:
        raise StoreError(f"{key} in {b.url} is damaged (its own checksum does not match); rewrite the node "
                         f"{node or '(root)'} (`illumix store verify` lists what else is damaged)")
    return entries


def check_document(b: Backend, node: str, rel: str, raw: bytes) -> None:
    """Refuse ``raw`` (the bytes of ``node/rel`` just read) unless the node's manifest has no entry
    for it or agrees; re-read both a few times first (module docstring: :data:`RECHECKS`). Bytes
    this process has already found in agreement with their manifest are accepted without reading
    it again (object stores read a cube's document on every request: one GET, not two)."""
    key = (b.url, node, rel)
    digest = sha256(raw)
    if _VERIFIED.get(key) == digest:
        return
    for attempt in range(RECHECKS + 1):
        entries = read_manifest(b, node)
        want = None if entries is None else entries.get(rel)
        if want is None:
            return
        if want == digest:
            _remember(key, digest)
            return
        if attempt < RECHECKS:
            time.sleep(RECHECK_S)
            digest = sha256(b.read_bytes(f"{node}/{rel}" if node else rel) or b"")
    raise StoreError(f"{node}/{rel} in {b.url} fails its checksum (its SHA-256 differs from the node's "
                     "manifest): the file was altered or damaged; rewrite this node and run `illumix store verify`")


#: ``(store, node, file) → SHA-256`` of documents found in agreement with their manifest (bounded)
_VERIFIED: OrderedDict[tuple[str, str, str], str] = OrderedDict()
_VERIFIED_MAX = 8192
_VERIFIED_LOCK = threading.Lock()


def _remember(key: tuple[str, str, str], digest: str) -> None:
    with _VERIFIED_LOCK:
        _VERIFIED[key] = digest
        _VERIFIED.move_to_end(key)
        while len(_VERIFIED) > _VERIFIED_MAX:
            _VERIFIED.popitem(last=False)


def check_node(b: Backend, node: str, bad, note, own: list[str] | None = None) -> int:
    """Verify every file under ``node`` (or only its ``own`` files, for a node whose sub-folders are
    nodes of their own: the root, a view, a registry entry) against its manifest: ``bad(where, what)``
    for a damaged, missing or unlisted file, ``note`` for a node without a manifest. Returns the
    files checked."""
    try:
        entries = read_manifest(b, node)
    except StoreError as exc:
        bad(node, str(exc))
        return 0
    if entries is None:
        note(node, "no checksums (written before illumix wrote them, or interrupted just before its manifest); "
                   "rewrite the node to add them")
        return 0
    present = [r for r in (own if own is not None else b.list_files(node)) if _counted(r)]
    present = [r for r in present if own is None or b.exists(f"{node}/{r}" if node else r)]
    for rel in present:
        want = entries.get(rel)
        if want is None:
            bad(f"{node}/{rel}", "a file the node's manifest does not list (added after it was written?); "
                                 "rewrite this node")
            continue
        data = b.read_bytes(f"{node}/{rel}" if node else rel)
        if data is None or sha256(data) != want:
            bad(f"{node}/{rel}", "fails its checksum (SHA-256 differs from the manifest): altered or damaged; "
                                 "rewrite this node")
    for rel in sorted(set(entries) - set(present)):
        bad(f"{node}/{rel}", "missing (listed in the node's manifest)")
    return len(present)


def check_empty_group(b: Backend, key: str, bad) -> bool:
    """An intermediate group's ``zarr.json`` must be exactly an empty group (stores written by older
    versions: the same content in zarr's own formatting)."""
    raw = b.read_bytes(f"{key}/zarr.json" if key else "zarr.json")
    if raw is None:
        return True
    if raw == EMPTY_GROUP_BYTES:
        return True
    try:
        ok = json.loads(raw) == EMPTY_GROUP
    except ValueError:
        ok = False
    if not ok:
        bad(key or "(root)", "damaged group metadata (zarr.json is not the empty group illumix writes); "
                             "rewrite the nodes below it")
    return ok


def partial_files(b: Backend) -> list[tuple[str, int | None, float]]:
    """``(key, writer pid or None, age in s)`` of every temporary ``.partial`` file or folder (left by
    a writer killed mid-write, e.g. ``zarr.json.<pid>.<id>.partial`` or a registry entry's
    ``.<name>.<pid>.<id>.partial/``; local stores only: object stores write in one PUT)."""
    if not b.local:
        return []
    out, seen = [], set()
    now = time.time()
    for rel in b.list_files(""):
        parts = rel.split("/")
        cut = next((i for i, p in enumerate(parts) if p.endswith(PARTIAL)), None)
        if cut is None:
            continue
        key = "/".join(parts[:cut + 1])
        if key in seen:
            continue
        seen.add(key)
        bits = parts[cut].split(".")
        pid = int(bits[-3]) if len(bits) >= 4 and bits[-3].isdigit() else None
        out.append((key, pid, now - b.mtime(key)))
    return out


def orphaned(pid: int | None, age_s: float, min_age_s: float) -> bool:
    """A partial file nobody will finish: its writer is dead (a local store is written from one host:
    the pid is this host's), or it is older than ``min_age_s`` (partials named before the pid was)."""
    if pid is not None:
        return not pid_alive(pid)
    return age_s >= min_age_s


def pid_alive(pid) -> bool:
    """Whether process ``pid`` (of this host) is running; True when that cannot be told."""
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, TypeError, ValueError, OverflowError):
        return True
    return True


def describe_chunk_error(exc: BaseException) -> str | None:
    """The one-line reason for a zarr decode failure that is a failed chunk checksum, else None."""
    text = str(exc)
    if "checksum" in text.lower():
        return "a chunk fails its CRC-32C checksum (the stored bytes were altered or damaged)"
    return None


__all__ = ["MANIFEST", "write_manifest", "read_manifest", "check_document", "check_node", "check_empty_group",
           "partial_files", "orphaned", "describe_chunk_error", "sha256"]
