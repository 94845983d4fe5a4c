"""Readers for the tabulated spectral file formats users bring.

- CSV: first column wavelength in nm, then one column per spectrum (a header row is optional;
  ``wavelength,value`` for an SPD, ``wavelength,r,g,b`` for a camera).
- rawtoaces camera JSON (``spectral_data.data.main`` maps ``"380"`` → ``[R, G, B]``).

Readers return raw samples; resampling to a grid is :func:`retarget.grid.resample`'s job.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError


def read_csv_table(source: str | Path | bytes, *, columns: int | None = None, what: str = "CSV"
                   ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Read a spectral CSV table.

    Returns ``(wavelengths (n,), values (n, k), column_names)``. ``columns`` (if given) is the
    number of value columns required (1 for an SPD, 3 for a camera).
    """
    text = _text(source, what)
    try:
        # splitlines() also ends a line at a bare CR, which csv.reader would refuse mid-field.
        rows = [r for r in csv.reader(text.splitlines()) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise SpectralError(f"{what}: not a readable CSV ({exc}); expected rows 'wavelength,value[,value…]'") from None
    rows = [r for r in rows if not r[0].lstrip().startswith("#")]
    if not rows:
        raise SpectralError(f"{what}: empty file; expected rows 'wavelength,value[,value…]'")
    names: list[str] = []
    try:
        float(rows[0][0])
    except ValueError:
        names = [c.strip() for c in rows[0][1:]]
        rows = rows[1:]
    if not rows:
        raise SpectralError(f"{what}: a header but no data rows; expected rows 'wavelength,value[,value…]'")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        # Checked first: numpy reports ragged rows as a ValueError, which would read "non-numeric".
        raise SpectralError(f"{what}: rows have different numbers of columns ({sorted(widths)})")
    try:
        data = np.array([[float(c) for c in r] for r in rows], dtype=np.float64)
    except ValueError as exc:
        raise SpectralError(f"{what}: non-numeric cell ({exc}); every row must be numbers") from None
    if data.ndim != 2 or data.shape[1] < 2:
        raise SpectralError(f"{what}: need a wavelength column and at least one value column")
    k = data.shape[1] - 1
    if columns is not None and k != columns:
        raise SpectralError(f"{what}: expected {columns} value column(s) after wavelength, found {k}")
    if not names or len(names) != k:
        names = [f"s{i}" for i in range(k)]
    return data[:, 0], data[:, 1:], names


def read_rawtoaces_camera(source: str | Path | bytes, what: str = "camera JSON"
                          ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Read a rawtoaces camera spectral-sensitivity JSON.

    Returns ``(wavelengths (n,), rgb (n, 3), header)``; the channels are reordered to R, G, B
    following ``spectral_data.index.main``.
    """
    text = _text(source, what)
    expected = "expected spectral_data.data.main mapping wavelength -> [R, G, B]"
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SpectralError(f"{what}: not a rawtoaces camera JSON (invalid JSON: {exc}); {expected}") from None
    except RecursionError:
        raise SpectralError(f"{what}: not a rawtoaces camera JSON (nested too deeply); {expected}") from None
    sd = doc.get("spectral_data") if isinstance(doc, dict) else None
    table = sd.get("data") if isinstance(sd, dict) else None
    table = table.get("main") if isinstance(table, dict) else None
    if not isinstance(table, dict) or not table:
        raise SpectralError(f"{what}: not a rawtoaces camera JSON; {expected}")
    index = sd.get("index", {"main": ["R", "G", "B"]})
    index = index.get("main") if isinstance(index, dict) else None
    if not isinstance(index, list) or sorted(str(c).upper() for c in index) != ["B", "G", "R"]:
        raise SpectralError(f"{what}: channel index {str(index)[:60]} is not R, G, B "
                            "(spectral_data.index.main lists the channels in file order)")
    index = [str(c).upper() for c in index]
    header = doc.get("header", {})
    if not isinstance(header, dict):
        raise SpectralError(f"{what}: 'header' must be an object, got {type(header).__name__}")
    rows = list(table.values())
    if not all(isinstance(v, list) and len(v) == 3 for v in rows):
        raise SpectralError(f"{what}: each wavelength needs exactly 3 values (R, G, B)")
    try:
        wl = np.array([float(k) for k in table], dtype=np.float64)
        vals = np.array([[float(x) for x in v] for v in rows], dtype=np.float64)
    except (ValueError, TypeError):
        raise SpectralError(f"{what}: wavelengths and values must be numbers") from None
    order = [index.index(c) for c in "RGB"]
    return wl, vals[:, order], dict(header)


def _text(source: str | Path | bytes, what: str) -> str:
    if isinstance(source, bytes):
        try:
            return source.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise SpectralError(f"{what}: not UTF-8 text") from None
    path = Path(source)
    if not path.is_file():
        raise SpectralError(f"{what}: no such file {str(path)!r}")
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise SpectralError(f"{what}: {str(path)!r} is not UTF-8 text") from None
