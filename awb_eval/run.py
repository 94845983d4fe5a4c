"""The evaluation loop: every case × every method → per-image scores (and a few error maps).

A case whose ground truth has no valid pixel, or an image that could not be made
(:class:`awb_eval.case.Unusable`), is skipped (counted, with the reason); method times
are wall-clock per image, the method alone (not the composition or the scoring).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from illumix.awb_eval.case import Case, Unusable
from illumix.awb_eval.methods import Method
from illumix.awb_eval.scoring import reference, score

MIN_SIDE = (12, 16)  # the ΔE00 grid's cells: an image needs at least one pixel per cell


@dataclass
class ErrorMaps:
    """Per-pixel angular errors of each method on one image, kept for the plots."""

    name: str
    srgb: np.ndarray  # (H, W, 3) the GT rendering
    mask: np.ndarray  # (H, W) bool
    errors: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W) degrees


@dataclass
class Results:
    images: list[dict] = field(default_factory=list)  # {name, pair, methods: {label: scores}}
    skipped: list[dict] = field(default_factory=list)  # {name, pair, why}
    maps: list[ErrorMaps] = field(default_factory=list)


def evaluate(cases: Iterable[Case | Unusable], methods: list[Method], *, maps: int = 0,
             on_case: Callable[[Case | Unusable, str], None] | None = None) -> Results:
    """Score ``methods`` on ``cases``; keep error maps of the first ``maps`` scored images.
    ``on_case(case, name)`` is called after each case (a progress bar)."""
    out = Results()
    for case in cases:
        why = case.why if isinstance(case, Unusable) else _unscorable(case)
        if why:
            out.skipped.append({"name": case.name, "pair": case.pair, "why": why})
        else:
            ref = reference(case)
            keep = ErrorMaps(case.name, ref.srgb, case.mask) if len(out.maps) < maps else None
            scores = {}
            for m in methods:
                t0 = time.perf_counter()
                gain = m.run(case)
                ms = 1e3 * (time.perf_counter() - t0)
                s, err = score(case, gain, ref)
                scores[m.label] = s | {"ms": ms}
                if keep is not None:
                    keep.errors[m.label] = err
            wp = case.white_points / case.white_points[:, 1:2]
            out.images.append({"name": case.name, "pair": case.pair, "pixels": int(case.mask.sum()),
                               "sensor": case.sensor, "white_points_rg_bg": np.round(wp[:, [0, 2]], 5).tolist(),
                               "methods": scores})
            if keep is not None:
                out.maps.append(keep)
        if on_case is not None:
            on_case(case, case.name)
    return out


def _unscorable(case: Case) -> str | None:
    h, w = case.shape
    if h < MIN_SIDE[0] or w < MIN_SIDE[1]:
        return f"{w}x{h} is smaller than the 16x12 ΔE00 grid"
    if not case.mask.any():
        return "no pixel with a defined ground truth (all dark or masked)"
    return None
