"""Test inputs for ``illumix evaluate``: a synthetic store and a small LSMI-layout folder.

The LSMI folder is written with cv2/numpy/tifffile the way the LSMI release lays out a camera (see
:mod:`awb_eval.lsmi_input`), independently of ``illumix export``: camera ``cam`` with places
``p0`` (lights 1, 12) and ``p1`` (lights 12, 123), a template ``cam.dng`` carrying BlackLevel 512,
WhiteLevel 16383 and a colour matrix.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import synthetic_store

BLACK, WHITE = 512, 16383
LIGHTS = {"Light1": [0.55, 1.0, 0.45], "Light2": [0.9, 1.0, 0.8], "Light3": [0.62, 1.0, 0.71]}
H, W = 36, 48


def make_store(path: Path) -> Path:
    """synth/v0 only (two groups, illumination cubes: the physical GT)."""
    synthetic_store.build(path, extras=False, illumination=True)
    return path


def lsmi_image(lights: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``(16-bit RGB tiff content, mixture or None, the raw after black subtraction)`` for a light set:
    grey texture lit by the lights' chromaticities mixed left→right, the bottom rows black."""
    n = len(lights)
    x = np.linspace(0, 1, W, dtype=np.float32)
    shares = [np.tile(x, (H, 1)), np.tile(1 - x, (H, 1)), np.full((H, W), 0.5, np.float32)][:n]
    mix = np.stack(shares, axis=-1) if n > 1 else np.ones((H, W, 1), np.float32)
    mix /= mix.sum(axis=-1, keepdims=True)
    chroma = np.array([LIGHTS[f"Light{i}"] for i in lights], np.float32)
    albedo = rng.uniform(0.2, 0.9, (H, W, 1)).astype(np.float32)
    raw = np.round(albedo * (mix @ chroma) * 9000).astype(np.float32)
    raw[-3:] = 0  # black: LSMI marks its mixture -1
    mix[-3:] = -1
    return (raw + BLACK).astype(np.uint16), (mix if n > 1 else None), raw


def make_lsmi(root: Path, *, dng: bool = True) -> Path:
    """The LSMI folder (module docstring); returns ``root``."""
    import tifffile

    cam = root / "cam"
    rng = np.random.default_rng(5)
    places = {"p0": ["1", "12"], "p1": ["12", "123"]}
    meta = {}
    for place, sets in places.items():
        (cam / place).mkdir(parents=True)
        meta[place] = dict(LIGHTS) | {"MCCCoord": {"mcc1": [[0, 0], [4, 0], [4, 4], [0, 4]]}}
        for lights in sets:
            tiff, mix, _ = lsmi_image(lights, rng)
            cv2.imwrite(str(cam / place / f"{place}_{lights}.tiff"), cv2.cvtColor(tiff, cv2.COLOR_RGB2BGR))
            if mix is not None:
                np.save(cam / place / f"{place}_{lights}.npy", mix)
    (cam / "meta.json").write_text(json.dumps(meta))
    (cam / "split.json").write_text(json.dumps({"multi_train": ["p0"], "multi_test": ["p1"]}))
    if dng:
        # XYZ → camera = XYZ → linear sRGB: the white-preserving CCM is then the identity
        import colour

        cm = colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB
        rationals = [v for c in cm.ravel() for v in (round(c * 1e6), 1_000_000)]
        tifffile.imwrite(root / "cam.dng", np.zeros((8, 8, 3), np.uint16), photometric="rgb",
                         extratags=[(50714, "H", 1, BLACK, True), (50717, "H", 1, WHITE, True),
                                    (50722, 10, 9, rationals, True)])
    return root
