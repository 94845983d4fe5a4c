"""The LSMI release's layout (Kim et al., "Large Scale Multi-Illuminant (LSMI) Dataset for Developing
White Balance Algorithm under Mixed Illumination", ICCV 2021; github.com/DY112/LSMI-dataset), one
camera per folder, so that LSMI's ``2_preprocess_data.py`` and ``SVWB_Unet`` dataloader read it
unchanged::

    OUT/<camera>.dng                       template: black level (min of black_level_per_channel),
                                           white level and CFA pattern, read with rawpy
    OUT/<camera>/meta.json                 {place: {"Light1": [r, g, b], …, "NumOfLights": k,
                                                    "MCCCoord": {"mcc1": 4 × [x, y], "mcc2", "mcc3"}, …}}
    OUT/<camera>/split.json                {"train": [places], "val": [...], "test": [...]}
    OUT/<camera>/illuminants.json          extra: every illuminant's name, CCT and SPD
    OUT/<camera>/<place>/<place>_<lights>.tiff   16-bit RGB raw, BGR order on disk (as cv2 writes),
                                           black level added, clipped at the white level
    OUT/<camera>/<place>/<place>_<lights>.npy    mixture (H, W, len(lights)) float32, multi-light only
    OUT/<camera>/<place>/<place>_<lights>_gt_illum.npy   extra: the ground truth (H, W, 3) float32

- ``Light<i>``: light ``i``'s white point in camera RGB normalised to G = 1 (LSMI's "green"
  normalisation), the ground truth's ``white_point_rgb``; LSMI's illumination map is
  ``Σ_i mixture_i · Light_i`` and its white balance ``raw / map``.
- Mixture: channel ``j`` belongs to light ``lights[j]``, the channels sum to 1; what it carries is
  ``--gt`` (:mod:`dataset_export.lsmi_target`): ``mixture`` (default) the light's share of the
  pixel's green (illumix's ``mixture`` output), ``physical`` the coefficients fitted so that LSMI's
  model ``Σ mixture·Light`` is illumix's physical ground truth (exactly where it is a mix of the
  lights), ``formula`` eq. 3.3's weights; ``-1`` (LSMI's ``ZERO_MASK``) where no
  light reaches the pixel or it has no surface (the sample's ``mask``) — never NaN, never another
  negative value (LSMI issues #9, #27).
- Lights of a ``--pairs`` place (and the default ``A,D65``) are assigned as ``/sample?pair=`` assigns
  them (:mod:`engine.lighting`): light 1 is the pair's first illuminant on every group it lights
  (the daylight illuminant on the view's daylight groups, where groups have kinds), light 2 the second.
- Ground truth (beyond LSMI): ``<place>_<lights>_gt_illum.npy``, every frame, is the sample's
  ``illum`` — the white point per pixel in camera RGB with G = 1, physical (bounce light included)
  unless ``--gt formula`` — and ``-1`` (``ZERO_MASK``) in all three channels where it is undefined
  (the mixture's ``-1`` pixels); never NaN. LSMI's model ``Σ mixture_i · Light_i`` is this only for
  formula ground truth (``LSMIModelErrorDeg``). LSMI's scripts list ``*.tiff`` and load the mixture
  by its exact name, so they never read it; the name avoids ``<fname>_illum.npy``, which LSMI's
  ``2_preprocess_data.py`` writes into its *output* folder.
- ``MCCCoord``: the ColorChecker's corners (:mod:`dataset_export.chart`), TL, TR, BR, BL, at **twice** the
  TIFF's pixel coordinates (LSMI annotated its full-size raws and ships half-size TIFFs; its scripts
  divide by 2). A scene has at most one chart found; absent charts (``mcc2``, ``mcc3``, or all when
  none is found) are four corners at ``(-2, -2)``: LSMI's script reads all three for the training
  split and fills each polygon in its mask, and ``(-2, -2) / 2`` lies outside the image, so an
  absent chart masks nothing. ``MCCCount`` says how many are real.
- Extra keys LSMI's code ignores: ``Illuminants`` (per light: ``name``, ``cct_K`` (K, a number, or
  null where the SPD has no CCT), ``duv``, the light's ``groups`` and its first ``group``), ``Scene``,
  ``View``, ``ExposureGain``, ``GroundTruth``, ``MixtureTarget`` (``--gt``), ``LSMIModelErrorDeg`` (the
  angle between LSMI's illumination model and illumix's ``illum``: 0 for formula ground truth, the
  bounce light's tint for the mixture target, what LSMI's model cannot express of it for physical).
- Place names hold no ``_`` (LSMI splits ``<place>_<lights>`` on it).
"""

from __future__ import annotations

import re

import numpy as np

from illumix.dataset_export.frames import Capture

ABSENT_CHART = [[-2.0, -2.0]] * 4
GT_ILLUM_SUFFIX = "_gt_illum.npy"  # <place>_<lights>_gt_illum.npy: the per-pixel ground truth (module docstring)
CHARTS = ("mcc1", "mcc2", "mcc3")


def camera_dir(sensor: str) -> str:
    """A folder name for a sensor (``Nikon 5100 (NPL)`` → ``Nikon-5100-NPL``)."""
    return re.sub(r"[^A-Za-z0-9.]+", "-", sensor).strip("-.") or "camera"


def mcc_coords(corners: np.ndarray | None) -> tuple[dict, int]:
    """``(MCCCoord, MCCCount)`` from the chart's pixel-index corners in the exported frame (or ``None``)."""
    coords = {name: [list(c) for c in ABSENT_CHART] for name in CHARTS}
    if corners is None:
        return coords, 0
    coords["mcc1"] = [[round(2 * float(x), 3), round(2 * float(y), 3)] for x, y in corners]
    return coords, 1


def place_entry(cap: Capture, corners: np.ndarray | None, gt: str, cct: dict[str, dict], target: str = "mixture") -> dict:
    """The place's ``meta.json`` entry (module docstring); ``cct``: illuminant name → ``{"cct_K": K or
    None, "duv": Duv}``; ``target``: what the mixture files carry (:data:`lsmi_target.TARGETS`)."""
    k = len(cap.chroma)
    coords, n_charts = mcc_coords(corners)
    groups = cap.groups or [[g] for g in cap.place.groups[:k]]
    entry: dict = {f"Light{i + 1}": [round(v, 8) for v in c] for i, c in enumerate(cap.chroma)}
    entry |= {"NumOfLights": k, "MCCCoord": coords, "MCCCount": n_charts,
              "Illuminants": [{"light": i + 1, "name": n, **cct[n], "group": gs[0] if gs else None, "groups": gs}
                              for i, (n, gs) in enumerate(zip(cap.place.lighting, groups))],
              "Scene": cap.place.scene, "View": cap.place.view, "ExposureGain": cap.exposure,
              "GroundTruth": gt, "MixtureTarget": target,
              "LSMIModelErrorDeg": {k2: round(v, 6) for k2, v in cap.lsmi_error_deg.items()}}
    return entry


def write_tiff(path, dn_rgb: np.ndarray) -> None:
    """16-bit RGB TIFF, channels in BGR order on disk as OpenCV writes (LSMI reads it with
    ``cv2.imread(…, IMREAD_UNCHANGED)`` + ``COLOR_BGR2RGB``)."""
    import cv2

    # encoded in memory (the bytes cv2.imwrite writes) and written here: a refused write is then an
    # OSError with its errno (ENOSPC …), where imwrite only answers False
    ok, buf = cv2.imencode(".tiff", np.ascontiguousarray(dn_rgb[..., ::-1], dtype=np.uint16))
    if not ok:
        raise ValueError(f"OpenCV could not encode a {dn_rgb.shape} TIFF for {path}")
    with open(path, "wb") as f:
        f.write(buf.tobytes())


def write_npy(path, mixture: np.ndarray) -> None:
    with open(path, "wb") as f:
        np.save(f, np.ascontiguousarray(mixture, dtype=np.float32))
