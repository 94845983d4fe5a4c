"""An estimated camera as a rawtoaces camera JSON (so it uploads and serves like any measured sensor),
with its provenance and uncertainty in the header; and the matrices a raw file carries."""

from __future__ import annotations

import datetime
import json
from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError


def camera_json(name: str, grid, curves: np.ndarray, samples: np.ndarray, provenance: dict) -> dict:
    """The rawtoaces document of ``curves`` ``(n_bands, 3)`` band averages on ``grid``, written at the
    band centres and one step beyond each end (the end values: a reader covering the grid's edges
    needs them), peak 1. The header states how it was made (``provenance``) and its uncertainty: the
    posterior ``samples``' standard deviation per band and channel, on the same scale."""
    peak = float(curves.max())
    wl = grid.wavelengths
    rows = np.vstack([curves[:1], curves, curves[-1:]]) / peak
    waves = np.concatenate([[wl[0] - grid.step], wl, [wl[-1] + grid.step]])
    std = samples.std(axis=0) / peak
    header = {"schema_version": "1.0.0", "manufacturer": "illumix estimate", "model": name,
              "description": "camera spectral sensitivity estimated from colour matrices under a prior "
                             "learned from measured cameras (illumix sensors estimate)",
              "document_creator": "illumix", "document_creation_date":
                  datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
              "license": "CC0-1.0", "comments": json.dumps(provenance, sort_keys=True),
              "illumix_estimate": {**provenance, "uncertainty": {
                  "what": "posterior standard deviation per band centre and channel (R, G, B), same scale",
                  "wavelengths_nm": [float(x) for x in wl], "std": np.round(std, 7).tolist()}}}
    data = {f"{w:g}": [round(float(v), 8) for v in row] for w, row in zip(waves, rows)}
    return {"header": header, "spectral_data": {"units": "relative", "index": {"main": ["R", "G", "B"]},
                                                "data": {"main": data}}}


def write_camera(path: str | Path, doc: dict) -> Path:
    """Write ``doc`` atomically (a temporary file renamed into place)."""
    p = Path(path)
    tmp = p.with_name(f".{p.name}.partial")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(doc, indent=1))
        tmp.replace(p)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise SpectralError(f"cannot write {p}: {exc.strerror or exc}") from None
    return p


#: EXIF LightSource codes DNG calibration illuminants use → illuminant names the library knows
LIGHT_SOURCES = {17: "A", 3: "A", 19: "C", 20: "D55", 21: "D65", 22: "D75", 23: "D50", 24: "A", 2: "FL2",
                 12: "FL1", 13: "FL2", 14: "FL3", 15: "FL7"}


def raw_matrices(path: str | Path) -> list[tuple[np.ndarray, str]]:
    """The ``[(XYZ → camera matrix (3, 3), calibration illuminant)]`` a raw file carries: a DNG's own
    ``ColorMatrix1/2`` with ``CalibrationIlluminant1/2``; any other raw LibRaw reads, its
    Adobe-derived D65 matrix (LibRaw's table)."""
    p = Path(path)
    if not p.is_file():
        raise SpectralError(f"{p}: {'is a directory' if p.is_dir() else 'does not exist'}")
    found = _dng_matrices(p)
    return found if found else [(_libraw_matrix(p), "D65")]


def _dng_tags(p: Path) -> dict:
    """The first IFD's tags of a DNG (code → value); empty for a file that is no TIFF."""
    import tifffile

    try:
        with tifffile.TiffFile(p) as tif:
            return {t.code: t.value for t in tif.pages[0].tags.values()}
    except Exception:  # noqa: BLE001 - not a TIFF/DNG: LibRaw may still read it
        return {}


CFA_COLOURS = {0: "R", 1: "G", 2: "B"}


def dng_sensor_model(path: str | Path) -> dict | None:
    """The camera's own sensor model a DNG states, for ``noise=camera``: black and white level (DN),
    the CFA pattern, and ``NoiseProfile``'s ``(S, O)`` — the variance of a signal ``x`` normalised to
    [0, 1] is ``S·x + O`` (DNG 1.6 §6.2) — of its first plane. None without a NoiseProfile."""
    tags = _dng_tags(Path(path))
    if 51041 not in tags:
        return None
    prof = np.asarray(tags[51041], np.float64).ravel()
    black = np.asarray(tags.get(50714, 0), np.float64).ravel()
    white = float(np.asarray(tags.get(50717, 4095), np.float64).ravel()[0])
    cfa = tags.get(33422)
    codes = list(cfa) if isinstance(cfa, (bytes, bytearray)) else np.asarray(cfa if cfa is not None else []).ravel()
    pattern = "".join(CFA_COLOURS.get(int(c), "?") for c in codes) if cfa is not None else None
    if prof.size < 2 or prof[0] <= 0 or prof[1] < 0 or not np.all(np.isfinite(prof[:2])):
        raise SpectralError(f"{path}: NoiseProfile {prof[:2].tolist()} is not (S > 0, O >= 0)")
    return {"black_level": float(black.mean()), "white_level": white, "noise_profile": [float(prof[0]), float(prof[1])],
            "bayer": pattern if pattern and len(pattern) == 4 and "?" not in pattern else None}


def _dng_matrices(p: Path) -> list[tuple[np.ndarray, str]]:
    tags = _dng_tags(p)
    if not tags:
        return []
    out = []
    for cm_code, ill_code in ((50721, 50778), (50722, 50779)):
        if cm_code not in tags:
            continue
        v = np.asarray(tags[cm_code], np.float64).ravel()
        m = (v[0::2] / np.where(v[1::2] == 0, 1, v[1::2])) if v.size == 18 else v
        if m.size != 9:  # a 4-colour camera's matrix (4x3) is not a 3-channel sensor
            raise SpectralError(f"{p}: ColorMatrix has {m.size} entries; only RGB (3x3) cameras can be estimated")
        code = int(np.ravel(tags.get(ill_code, 21))[0])
        if code not in LIGHT_SOURCES:
            raise SpectralError(f"{p}: calibration illuminant code {code} is not one this library knows "
                                f"({', '.join(f'{k}={v}' for k, v in sorted(LIGHT_SOURCES.items()))}); give the "
                                "matrix with --color-matrix and --calibration-illuminant instead")
        out.append((m.reshape(3, 3), LIGHT_SOURCES[code]))
    return out


def with_raw(path: str | Path, read, what: str):
    """``read(rawpy object)`` of a raw file LibRaw opens; one-line errors for a missing rawpy (``what``
    names the option) or an unreadable file."""
    try:
        import rawpy
    except ImportError:
        raise SpectralError(f"{what} needs rawpy: pip install 'illumix[export]'") from None
    try:
        with rawpy.imread(str(path)) as raw:
            return read(raw)
    except (rawpy.LibRawError, OSError) as exc:
        raise SpectralError(f"{path}: not a raw file LibRaw can read ({type(exc).__name__}: {exc})") from None


def _libraw_matrix(path: Path) -> np.ndarray:
    """LibRaw's D65 XYZ → camera matrix of a raw file's camera (its Adobe-derived table)."""
    m = with_raw(path, lambda raw: np.asarray(raw.rgb_xyz_matrix, np.float64)[:3], "--from-raw")
    if not np.any(m):
        raise SpectralError(f"{path}: carries no colour matrix (LibRaw knows none for this camera)")
    return m
