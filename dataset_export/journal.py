"""Atomic writes, resumable runs and checksums: the export's journal and ``manifest.json``.

Every file is written under a temporary name in its folder and renamed into place
(``os.replace``), so a file under its final name is always complete; an interrupted run leaves at
most a temporary ``.<stem>.illumix-tmp<ext>`` (:func:`temp_path`), which the next run removes. No
exported name can look like one: place and camera names never start with ``.``, and only regular
files matching that pattern exactly are removed (store names may hold ``.``, e.g. ``demo.party``). After each rename the file's SHA-256 and size are
appended to ``.export-journal.jsonl`` (one JSON object per line, flushed), with the run's parameters
on the first line. A rerun with the same parameters skips every file whose bytes still match the
journal (a damaged or foreign file is written again); other parameters are refused, so one folder
never mixes two exports. ``manifest.json`` lists every file with its checksum at the end.

A write the disk refuses (full, read-only, failing) raises :class:`~dataset_export.errors.ExportWriteError`
naming the file, after removing its temporary: the folder then holds complete files only, and the
same command resumes once there is space. A journal line cut by a full disk is skipped when read
(its file is written again) and never glued to the next one.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable
from pathlib import Path

from illumix.dataset_export.errors import ExportError, ExportWriteError, system_error

JOURNAL = ".export-journal.jsonl"
MANIFEST = "manifest.json"
TEMP_TAG = ".illumix-tmp"
_TEMP_NAME = re.compile(r"^\..+" + re.escape(TEMP_TAG) + r"(\.[A-Za-z0-9]+)?$")


def temp_path(dst: Path) -> Path:
    """The temporary name ``dst`` is written under: ``.<stem>.illumix-tmp<ext>`` in its folder (same
    extension, so libraries that pick the format by it still do)."""
    return dst.with_name(f".{dst.stem}{TEMP_TAG}{dst.suffix}")


def is_temp(path: Path) -> bool:
    """A leftover of an interrupted :meth:`Journal.write`: a regular file named as :func:`temp_path` names."""
    return bool(_TEMP_NAME.match(path.name)) and path.is_file() and not path.is_symlink()


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class Journal:
    """The record of a (possibly interrupted) export into ``root`` with ``parameters``."""

    def __init__(self, root: Path, parameters: dict) -> None:
        self.root = Path(root)
        self.parameters = parameters
        self.files: dict[str, dict] = {}
        self.records: dict[str, dict] = {}  # key → JSON-able data a resumed run needs (e.g. a place's meta)
        self._cut = False  # the journal's last line was cut (a full disk): start the next one on a new line
        path = self.root / JOURNAL
        if path.exists():
            self._load(path)
        else:
            try:
                self.root.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ExportWriteError.of(exc, self.root) from exc
            self._append({"parameters": parameters})
        for path in self.root.rglob(f".*{TEMP_TAG}*"):  # leftovers of an interrupted write
            if is_temp(path):
                path.unlink(missing_ok=True)

    def _load(self, path: Path) -> None:
        text = path.read_text()
        self._cut = bool(text) and not text.endswith("\n")
        lines = text.splitlines()
        entries = []
        for line in lines:
            try:
                entries.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line cut by an interruption: what it recorded is written again
        first = entries[0].get("parameters") if entries else None
        if first != self.parameters:
            diff = sorted(k for k in set(first or {}) | set(self.parameters) if (first or {}).get(k) != self.parameters.get(k))
            raise ExportError(f"{self.root} holds an export made with other parameters (differing: "
                            f"{', '.join(diff) or 'unknown'}); export into a new folder, or delete that one")
        for e in entries[1:]:
            if "file" in e:
                self.files[e["file"]] = e
            elif "record" in e:
                self.records[e["record"]] = e["data"]

    def _append(self, entry: dict) -> None:
        line = json.dumps(entry, separators=(",", ":")) + "\n"
        try:
            with open(self.root / JOURNAL, "a") as f:
                f.write("\n" + line if self._cut else line)
                f.flush()
                os.fsync(f.fileno())
        except OSError as exc:
            self._cut = True  # perhaps part of the line was written
            raise ExportWriteError.of(exc, self.root / JOURNAL) from exc
        self._cut = False

    def complete(self, rel: str) -> bool:
        """Whether ``rel`` was written by this export and its bytes are unchanged."""
        e = self.files.get(rel)
        p = self.root / rel
        return e is not None and p.is_file() and p.stat().st_size == e["bytes"] and sha256(p) == e["sha256"]

    def write(self, rel: str, writer: Callable[[Path], None]) -> Path:
        """Write ``rel`` atomically: ``writer(tmp_path)`` writes the whole file under a temporary name
        (same extension, so libraries that pick the format by it still do), then it is renamed."""
        dst = self.root / rel
        tmp = temp_path(dst)
        try:
            dst.parent.mkdir(parents=True, exist_ok=True)
            writer(tmp)
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
            os.replace(tmp, dst)
        except OSError as exc:
            raise ExportWriteError.of(exc, dst) from exc
        except Exception as exc:
            if (cause := system_error(exc)) is None:  # a library's own error naming a refused write
                raise
            raise ExportWriteError.of(cause, dst) from exc
        finally:
            tmp.unlink(missing_ok=True)
        entry = {"file": rel, "sha256": sha256(dst), "bytes": dst.stat().st_size}
        self.files[rel] = entry
        self._append(entry)
        return dst

    def write_bytes(self, rel: str, data: bytes) -> Path:
        return self.write(rel, lambda p: p.write_bytes(data))

    def write_json(self, rel: str, obj) -> Path:
        return self.write_bytes(rel, (json.dumps(obj, indent=2, allow_nan=False) + "\n").encode())

    def record(self, key: str, data) -> None:
        """Keep ``data`` (JSON-able) for a resumed run, e.g. a place's metadata composed with its frames."""
        self.records[key] = data
        self._append({"record": key, "data": data})

    def done(self, key: str) -> dict | None:
        """The record ``key`` if every file it lists (``record["files"]``) is complete — a resumed run
        skips that work — else ``None``."""
        rec = self.records.get(key)
        if rec is not None and all(self.complete(f) for f in rec["files"]):
            return rec
        return None

    def manifest(self, extra: dict) -> dict:
        """``manifest.json``'s content: the parameters, ``extra`` and every file's checksum."""
        files = {rel: {"sha256": e["sha256"], "bytes": e["bytes"]}
                 for rel, e in sorted(self.files.items()) if rel != MANIFEST}
        return {"parameters": self.parameters, **extra, "files": files}


def verify_manifest(root: Path) -> list[str]:
    """The files of ``root/manifest.json`` that are missing or whose checksum differs (empty: intact)."""
    man = json.loads((Path(root) / MANIFEST).read_text())
    bad = []
    for rel, e in man["files"].items():
        p = Path(root) / rel
        if not p.is_file() or sha256(p) != e["sha256"]:
            bad.append(rel)
    return bad
