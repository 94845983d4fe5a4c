"""Evaluation cases from a dataset in the LSMI layout (Kim et al., "Large Scale Multi-Illuminant
(LSMI) Dataset for Developing White Balance Algorithm under Mixed Illumination", ICCV 2021), as the
LSMI release and ``illumix export --format lsmi`` lay out one camera::

    ROOT/<camera>.dng                      template: black and white level, colour matrix
    ROOT/<camera>/meta.json                place → {"Light1".."Light3": camera-RGB chromaticity, "MCCCoord"}
    ROOT/<camera>/split.json               {"<…>_train"|"…_val"|"…_test": [place, …]}
    ROOT/<camera>/<place>/<place>_<lights>.tiff   16-bit RGB raw with black level (BGR on disk, OpenCV order)
                                           (or ``.dng``: read as LSMI's ``0_cvt2tiff.py`` converts its
                                           cameras' raws, :mod:`awb_eval.dng_frames`)
    ROOT/<camera>/<place>/<place>_<lights>.npy    mixture H×W×len(lights), -1 where black (not for one light)

read as LSMI's own ``2_preprocess_data.py`` reads it: ``raw = clip(tiff - black, 0, white - black)``,
the GT illumination map ``Σ_i mix_i · Light_i`` (LSMI ``utils.mix_chroma``), invalid where the mixture
is -1 — unless the file has the exact ground truth beside it, ``<place>_<lights>_gt_illum.npy``
(``illumix export`` writes it: the per-pixel white point ``(H, W, 3)``, physical, -1 where undefined),
which is then preferred (LSMI's model cannot hold the bounce light's tint); :meth:`LsmiCases.describe`
says which ground truth was used (``gt``). Black level ``min(black_level_per_channel)`` and white level as LSMI takes them from the
template DNG (rawpy when installed, else the DNG's BlackLevel/WhiteLevel tags read with tifffile),
unless given. The CCM used for the ΔE00 rendering is the DNG's colour matrix made white-preserving
(dcraw's ``cam_xyz_coeff``), identity when the DNG has none.
"""

from __future__ import annotations

import json
import math
import random
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from illumix.awb_eval.case import Case, unsaturated
from illumix.awb_eval.dng_frames import half_size, read_dng_rgb
from illumix.retarget.errors import SpectralError, unknown_name

ZERO_MASK = -1.0  # LSMI's mixture value where a pixel is black
_FILE = re.compile(r"^(?P<place>.+)_(?P<lights>[1-9]+)\.(?P<ext>tiff|dng)$")
GT_ILLUM_SUFFIX = "_gt_illum.npy"  # the exact per-pixel ground truth beside <place>_<lights>.tiff
# DNG tags (Adobe DNG specification 1.6): BlackLevel, WhiteLevel, ColorMatrix1/2, CalibrationIlluminant1/2
_BLACK, _WHITE, _CM1, _CM2, _CAL1, _CAL2 = 50714, 50717, 50721, 50722, 50778, 50779
_TAGS = (_BLACK, _WHITE, _CM1, _CM2, _CAL1, _CAL2)


def is_lsmi(path: str | Path) -> bool:
    """An LSMI camera folder (``meta.json`` + ``split.json``) or a folder of them."""
    p = Path(path)
    return (p / "meta.json").is_file() or any(p.glob("*/meta.json"))


@dataclass
class CameraLevels:
    """Black and white level (LSMI's BLACK_LEVEL, SATURATION) and the camera's colour matrix."""

    black: float
    white: float
    cam_xyz: np.ndarray | None  # (3, 3) XYZ → camera (DNG ColorMatrix), None when unknown
    source: str


def read_levels(dng: Path) -> CameraLevels:
    """Black/white level and colour matrix of a template DNG. The levels as LSMI reads them: rawpy
    (libraw) when installed and it opens the file, else the DNG's BlackLevel/WhiteLevel tags; the
    colour matrix from the DNG's ColorMatrix tags (libraw leaves ``rgb_xyz_matrix`` zero for a camera
    it does not know), else libraw's."""
    tags = _dng_tags(dng)
    cam_xyz = _colour_matrix(tags)
    try:
        import rawpy
    except ImportError:
        rawpy = None
    libraw_error = ""
    if rawpy is not None:
        try:
            with rawpy.imread(str(dng)) as r:
                m = np.asarray(r.rgb_xyz_matrix, dtype=np.float64)[:3]
                return CameraLevels(float(min(r.black_level_per_channel)), float(r.white_level),
                                    cam_xyz if cam_xyz is not None else (m if np.any(m) else None),
                                    f"{dng.name} (rawpy)")
        except Exception as exc:  # noqa: BLE001 — libraw raises its own types; the tags may still say it
            libraw_error = f" (libraw: {type(exc).__name__}: {exc})"
    if _BLACK not in tags or _WHITE not in tags:
        raise SpectralError(f"{dng}: no BlackLevel/WhiteLevel tags{libraw_error}; give --black-level and "
                            "--white-level" + ("" if rawpy else " or install rawpy (pip install 'illumix[evaluate]')"))
    return CameraLevels(float(tags[_BLACK].min()), float(tags[_WHITE].max()), cam_xyz, f"{dng.name} (DNG tags)")


def _dng_tags(dng: Path) -> dict[int, np.ndarray]:
    """The DNG tags this module reads, from IFD0 and its SubIFDs (the first found wins)."""
    import tifffile

    found: dict[int, np.ndarray] = {}
    try:
        with tifffile.TiffFile(str(dng)) as tif:
            pages = list(tif.pages)
            for page in list(pages):
                pages.extend(page.pages or [])
            for page in pages:
                for code in _TAGS:
                    tag = page.tags.get(code)
                    if tag is not None and code not in found:
                        found[code] = _tag_numbers(tag.value, int(tag.dtype))
    except Exception as exc:  # noqa: BLE001 — tifffile raises many kinds; one line for all
        raise SpectralError(f"{dng}: not a readable DNG ({type(exc).__name__}: {exc})") from None
    return found


def _colour_matrix(tags: dict[int, np.ndarray]) -> np.ndarray | None:
    """XYZ → camera ``(3, 3)``: the ColorMatrix calibrated under D65 (CalibrationIlluminant 21), else
    ColorMatrix2 (the daylight side in most DNGs), else ColorMatrix1; None without one."""
    d65 = [cm for cm, ill in ((_CM1, _CAL1), (_CM2, _CAL2)) if cm in tags and ill in tags and tags[ill][0] == 21]
    for code in (*d65, _CM2, _CM1):
        if code in tags and tags[code].size == 9:
            return tags[code].reshape(3, 3)
    return None


def _tag_numbers(value, dtype: int) -> np.ndarray:
    """A TIFF tag's value as floats; RATIONAL (5) and SRATIONAL (10) come as flat numerator,
    denominator pairs from tifffile."""
    a = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    if dtype in (5, 10):
        den = a[1::2]
        return a[0::2] / np.where(den == 0, 1.0, den)
    return a


def white_preserving_ccm(cam_xyz: np.ndarray | None) -> np.ndarray:
    """Camera (white-balanced) → linear sRGB ``(3, 3)`` float32 from a DNG colour matrix (XYZ → camera),
    as dcraw's ``cam_xyz_coeff``: ``cam_rgb = cam_xyz · M_sRGB→XYZ``, rows normalised to sum 1 (so
    white maps to white), inverted. Identity without a matrix."""
    if cam_xyz is None:
        return np.eye(3, dtype=np.float32)
    import colour

    cam_rgb = np.asarray(cam_xyz, dtype=np.float64) @ colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ
    sums = cam_rgb.sum(axis=1, keepdims=True)
    if np.any(np.abs(sums) < 1e-12) or abs(np.linalg.det(cam_rgb)) < 1e-12:
        raise SpectralError("the DNG's colour matrix is singular; no camera → sRGB matrix exists")
    return np.linalg.inv(cam_rgb / sums).astype(np.float32)


@dataclass(frozen=True)
class Item:
    place: str
    lights: str
    raw: Path  # the .tiff, or the .dng of a DNG export

    @property
    def name(self) -> str:
        return f"{self.place}_{self.lights}"

    @property
    def gt_illum(self) -> Path:
        return self.raw.with_name(self.name + GT_ILLUM_SUFFIX)


class LsmiCases:
    """The cases of an LSMI folder (module docstring); ``len()`` first, then iterate.

    camera : which camera folder (needed when ROOT holds several); pairs : LSMI light sets to keep
    (``"12;13"``; default all); split : keep places of this split only (``train``/``val``/``test``);
    count, seed : only ``count`` places drawn with ``seed``; black_level, white_level : override the DNG.
    """

    kind = "lsmi"

    def __init__(self, root: str | Path, *, camera: str | None = None, pairs: str | None = None,
                 count: int | None = None, seed: int = 0, split: str | None = None,
                 black_level: float | None = None, white_level: float | None = None) -> None:
        root = Path(root)
        if (root / "meta.json").is_file():  # ROOT is the camera folder itself
            root, camera_dir = root.parent, root
            if camera is not None and camera != camera_dir.name:
                raise SpectralError(f"{camera_dir} is camera {camera_dir.name!r}, not {camera!r}")
        else:
            cameras = sorted(p.parent.name for p in root.glob("*/meta.json"))
            if camera is None:
                if len(cameras) > 1:
                    raise SpectralError(f"{root} holds cameras {', '.join(cameras)}; choose one with --sensor")
                camera = cameras[0]
            elif camera not in cameras:
                raise unknown_name("camera", camera, cameras)
            camera_dir = root / camera
        self.root, self.camera_dir, self.camera = root, camera_dir, camera_dir.name
        self.meta = _read_json(camera_dir / "meta.json")
        places = self._places(split)
        if count is not None and count < len(places):
            places = sorted(random.Random(seed).sample(places, count))
        keep = None if pairs is None else {p.strip() for p in str(pairs).replace(",", ";").split(";") if p.strip()}
        self.items = [it for pl in places for it in self._files(pl) if keep is None or it.lights in keep]
        if not self.items:
            what = f" with lights {sorted(keep)}" if keep else ""
            raise SpectralError(f"{camera_dir}: no <place>_<lights>.tiff (or .dng){what} in the chosen places "
                                f"({len(places)}); LSMI light sets are digits, e.g. --pairs \"12;13\"")
        self.levels = self._levels(black_level, white_level)
        self.ccm = white_preserving_ccm(self.levels.cam_xyz)
        self.split, self.seed, self.pairs = split, seed, pairs
        self.gt_files = sum(it.gt_illum.is_file() for it in self.items)
        self.dng_files = sum(it.raw.suffix == ".dng" for it in self.items)

    def _places(self, split: str | None) -> list[str]:
        splits = _read_json(self.camera_dir / "split.json")
        chosen = {k: v for k, v in splits.items() if split is None or k.split("_")[-1] == split}
        if not chosen:
            names = sorted({k.split("_")[-1] for k in splits})
            raise SpectralError(f"{self.camera_dir / 'split.json'} has no split {split!r} (splits: {', '.join(names)})")
        places = sorted({p for v in chosen.values() for p in v})
        if not places and split is not None:  # the real cause, before "no <place>_<lights>.tiff"
            sizes = ", ".join(f"{k.split('_')[-1]} {len(v)}" for k, v in splits.items())
            raise SpectralError(f"{self.camera_dir / 'split.json'}: the {split} split is empty (places per split: "
                                f"{sizes}); choose another --split, or export more scenes (splits are by scene: an "
                                "export of fewer scenes than splits leaves some empty)")
        return places

    def _files(self, place: str) -> list[Item]:
        folder = self.camera_dir / place
        if not folder.is_dir():
            raise SpectralError(f"{folder}: listed in split.json but missing")
        if place not in self.meta:
            raise SpectralError(f"{self.camera_dir / 'meta.json'} has no entry for place {place!r}")
        found: dict[str, Path] = {}
        for f in sorted(folder.glob(f"{place}_*")):
            m = _FILE.match(f.name)
            if m and m["place"] == place and (m["lights"] not in found or m["ext"] == "tiff"):  # a TIFF first
                found[m["lights"]] = f
        return [Item(place, lights, f) for lights, f in sorted(found.items())]

    def _levels(self, black: float | None, white: float | None) -> CameraLevels:
        dng = self.root / f"{self.camera}.dng"
        if black is not None and white is not None:
            cam = read_levels(dng).cam_xyz if dng.is_file() else None
            levels = CameraLevels(float(black), float(white), cam, "given")
        elif not dng.is_file():
            raise SpectralError(f"no template {dng.name} beside {self.camera_dir} for the black and white level; "
                                "put it there or give --black-level and --white-level")
        else:
            levels = read_levels(dng)
            if black is not None or white is not None:
                levels.black = levels.black if black is None else float(black)
                levels.white = levels.white if white is None else float(white)
        if not (math.isfinite(levels.white) and math.isfinite(levels.black)):
            raise SpectralError(f"{dng.name} / --black-level, --white-level: levels must be finite, got black "
                                f"{levels.black:g}, white {levels.white:g}")
        if not levels.white > levels.black:  # given or read: every pixel would clip to nothing
            raise SpectralError(f"{dng.name} / --black-level, --white-level: white level {levels.white:g} is not above "
                                f"the black level {levels.black:g}")
        return levels

    def __len__(self) -> int:
        return len(self.items)

    def describe(self) -> dict:
        return {"kind": self.kind, "path": str(self.camera_dir), "camera": self.camera, "images": len(self.items),
                "places": len({i.place for i in self.items}), "split": self.split, "pairs": self.pairs,
                "seed": self.seed, "black_level": self.levels.black, "white_level": self.levels.white,
                "levels_from": self.levels.source,
                "ccm": "DNG colour matrix" if self.levels.cam_xyz is not None else "identity (no colour matrix)",
                "gt": self._gt_used(), "raw": self._raw_read()}

    def _raw_read(self) -> str:
        tiff = "16-bit RGB TIFFs (cv2)"
        dng = ("DNG raws via libraw: Bayer → half-size RGB as LSMI's 0_cvt2tiff.py (dcraw -h -D), maps averaged "
               "over 2×2 blocks; LinearRaw as is")
        return dng if self.dng_files == len(self.items) else tiff if not self.dng_files else f"{tiff} and {dng}"

    def _gt_used(self) -> str:
        model = "LSMI model Σ mixture·Light (meta.json Light<i>)"
        exact = f"per-pixel <place>_<lights>{GT_ILLUM_SUFFIX} (illumix export's ground truth)"
        if self.gt_files == len(self.items):
            return exact
        if not self.gt_files:
            return model
        return f"{exact} for {self.gt_files} of {len(self.items)} images, {model} for the others"

    def __iter__(self) -> Iterator[Case]:
        for item in self.items:
            yield self.load(item)

    def load(self, item: Item) -> Case:
        """One file → :class:`Case` (LSMI's reading; module docstring)."""
        if item.raw.suffix == ".dng":
            dn, (h, w) = read_dng_rgb(item.raw)  # the maps are per pixel of the file: a Bayer DNG's, 2× its RGB
        else:
            img = cv2.imread(str(item.raw), cv2.IMREAD_UNCHANGED)
            if img is None or img.ndim != 3 or img.shape[2] != 3:
                raise SpectralError(f"{item.raw}: not a 3-channel image OpenCV can read")
            dn = cv2.cvtColor(img, cv2.COLOR_BGR2RGB).astype(np.float32)
            h, w = dn.shape[:2]
        top = self.levels.white - self.levels.black
        raw = np.clip(dn - np.float32(self.levels.black), 0, top)
        n = len(item.lights)
        if n == 1:
            mix = np.ones((h, w, 1), np.float32)
        else:
            npy = item.raw.with_suffix(".npy")
            if not npy.is_file():
                raise SpectralError(f"{npy}: missing (the mixture of a {n}-light image)")
            mix = _load_npy(npy, (h, w, n))
        mask = np.all(np.isfinite(mix), axis=-1) & (mix[..., 0] != ZERO_MASK) & np.all(mix >= 0, axis=-1)
        mix = np.where(mask[..., None], mix, np.float32(0))
        chroma = []
        for i in item.lights:
            light = self.meta[item.place].get(f"Light{i}")
            try:
                values = [float(v) for v in light] if isinstance(light, (list, tuple)) else []
            except (TypeError, ValueError):
                values = []
            if len(values) != 3 or not all(v > 0 for v in values):  # NaN fails v > 0 too
                raise SpectralError(f"{self.camera_dir / 'meta.json'}: {item.place}.Light{i} must be 3 positive "
                                    f"camera-RGB values, got {light!r}")
            chroma.append(values)
        wps = np.array(chroma)
        if item.gt_illum.is_file():
            illum = _load_npy(item.gt_illum, (h, w, 3))
        else:
            illum = (mix @ wps.astype(np.float32)).astype(np.float32)  # LSMI mix_chroma
        mask &= np.all(np.isfinite(illum), axis=-1) & np.all(illum > 0, axis=-1)
        if raw.shape[:2] != (h, w):  # a Bayer DNG read at half size
            mask, mix, illum = half_size(mask), half_size(mix), half_size(illum)
        fill = illum[mask].mean(axis=0) if mask.any() else np.ones(3, np.float32)
        illum[~mask] = fill  # any positive colour: never scored, keeps gains finite
        return Case(name=item.name, pair=item.lights, raw=raw, illum=illum, mask=mask, mixture=mix,
                    white_points=wps, ccm=self.ccm, usable=unsaturated(raw, top))


def _load_npy(path: Path, shape: tuple[int, int, int]) -> np.ndarray:
    """A mixture or ``_gt_illum`` ``.npy`` file as ``shape`` float32 (no pickles; its undefined pixels
    are left for the caller's mask)."""
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise SpectralError(f"{path}: not a readable .npy ({exc})") from None
    if a.shape != shape:
        raise SpectralError(f"{path}: shape {a.shape}, expected {shape} (the image's H × W × channels)")
    if a.dtype.kind not in "biuf":
        raise SpectralError(f"{path}: dtype {a.dtype}, expected numbers (float32)")
    return np.asarray(a, np.float32)


def _read_json(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise SpectralError(f"{path}: missing (an LSMI camera folder has meta.json and split.json)") from None
    except (OSError, ValueError) as exc:
        raise SpectralError(f"{path}: not readable JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise SpectralError(f"{path}: expected a JSON object")
    return doc
