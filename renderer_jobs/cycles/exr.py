"""Read the multilayer OpenEXR files Blender writes (the Cycles backend's passes, environment maps)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def read_exr(path: Path) -> dict[str, np.ndarray]:
    """Layers of a multilayer EXR by name (``ViewLayer.`` stripped): ``(H, W, C)`` float32."""
    import OpenEXR

    out: dict[str, np.ndarray] = {}
    with OpenEXR.File(str(path), separate_channels=False) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                px = np.asarray(ch.pixels, dtype=np.float32)
                name = name.split(".", 1)[1] if name.startswith("ViewLayer.") else name
                if px.ndim == 2:  # a one-channel layer comes as "<layer>.X"
                    name, px = name.rsplit(".", 1)[0], px[..., None]
                out[name] = px
    return out
