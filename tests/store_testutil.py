"""Helpers shared by the tests/test_store_*.py files (not a test module)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from illumix.retarget.grid import DEFAULT_GRID
from illumix.store import CubeMeta, CubeStore, ViewMeta
from illumix.store.synth import synthetic_cube

#: Small frames whose sides are not multiples of the 32 px test tile (edge chunks are partial).
H, W, TILE = 48, 80, 32
NB = DEFAULT_GRID.n_bands


def new_store(path: Path, **kw) -> CubeStore:
    kw.setdefault("tile", TILE)
    return CubeStore.open(path, mode="a", **kw)


def add_view(st: CubeStore, scene: str = "s", view: str = "v", h: int = H, w: int = W,
             groups: list[str] | None = None, aovs: dict | None = None) -> ViewMeta:
    return st.write_view(scene, view, ViewMeta(width=w, height=h, fov=50.0, groups=groups or []), aovs)


def meta(**kw) -> CubeMeta:
    kw.setdefault("grid", DEFAULT_GRID)
    return CubeMeta(**kw)


def cube(h: int = H, w: int = W, seed: int = 0) -> np.ndarray:
    """A small render-like cube (smooth regions, shadows, an emitter, 10 % noise)."""
    return synthetic_cube(h, w, seed=seed)
