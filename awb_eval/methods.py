"""AWB methods as ``raw → per-pixel gain map``, dispatched by name (:data:`awb_eval.method_names.AWB_METHODS`).

Every method answers a gain map ``(H, W, 3)`` float32 (a global method broadcasts one gain). Gains
follow the ground truth's convention (thesis eq. 3.3): for an illuminant estimate ``e``,
``gain_k = max_j e_j / e_k``, so the method's implied illuminant is ``1 / gain`` (up to scale).

- statistical methods (:mod:`awb_eval.statistical`): e^{n,p,σ} of van de Weijer et al. 2007,
  globally or patch-wise; parameters overridable (``p``, ``sigma``, ``grid``, ``interpolation``);
- oracles, which read the ground truth (a :class:`awb_eval.case.Case`): ``Ground Truth`` and the
  thesis' ``Weighted Average`` single white point (§5.2);
- plug-ins ``module.path:callable``: a user's model, called as ``fn(raw)`` with raw ``(H, W, 3)``
  float32, answering a gain map ``(H, W, 3)`` (or ``(3,)``, broadcast).
"""

from __future__ import annotations

import difflib
import importlib
import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from illumix.awb_eval.case import Case
from illumix.awb_eval.method_names import AWB_METHODS, PATCH_PREFIX, is_plugin
from illumix.awb_eval.statistical import estimate
from illumix.retarget import global_wb
from illumix.retarget.errors import SpectralError
from illumix.retarget.groundtruth import gain_map

# name → (order n, Minkowski p, Gaussian σ in pixels): e^{n,p,σ}. The Gray-Edge settings are the ones
# the colour constancy survey reports for its 1st- and 2nd-order Gray-Edge runs (Gijsenij, Gevers & van
# de Weijer, IEEE TIP 20(9), 2011): e^{1,1,6} and e^{2,1,1}. Measured on the demo rooms (bench/EVALUATE.md),
# the authors' demo setting p = 5, σ = 2 is 1.7-2.4° worse: a high p lets a few coloured object edges decide.
STATISTICAL = {
    "Gray World": (0, 1.0, 0.0),
    "White Patch": (0, math.inf, 0.0),
    "Shades of Gray": (0, 6.0, 0.0),
    "Gray Edge": (1, 1.0, 6.0),
    "2nd Order Gray Edge": (2, 1.0, 1.0),
}
DEFAULT_GRID = (4, 4)


def gain_from_illuminant(illum: np.ndarray) -> np.ndarray:
    """``gain_k = max_j e_j / e_k`` (thesis eq. 3.3) of an illuminant map ``(H, W, 3)``, float32."""
    return gain_map(np.asarray(illum, dtype=np.float32))


def statistical_gain(raw: np.ndarray, method: str = "Gray World", *, valid: np.ndarray | None = None,
                     p: float | None = None, sigma: float | None = None, grid: tuple[int, int] | None = None,
                     interpolation: str = "bilinear") -> np.ndarray:
    """Gain map of a statistical method (``"Gray World"``, ``"Patch Shades of Gray"``, …).

    ``p``, ``sigma`` override the method's Minkowski norm and Gaussian scale; ``grid`` (rows, cols)
    the patch-wise grid (default 4×4; global methods use 1×1 unless given one).
    """
    name = AWB_METHODS.canonical(method)
    base = name.removeprefix(PATCH_PREFIX)
    if base not in STATISTICAL:
        raise SpectralError(f"{name!r} is not a statistical AWB method (those are: {', '.join(STATISTICAL)} "
                            "and their Patch versions)")
    order, p0, s0 = STATISTICAL[base]
    cells = grid if grid is not None else (DEFAULT_GRID if name.startswith(PATCH_PREFIX) else (1, 1))
    e = estimate(raw, order, p0 if p is None else p, s0 if sigma is None else sigma, cells, interpolation, valid)
    return gain_from_illuminant(e)


def ground_truth_gain(case: Case) -> np.ndarray:
    """The ground truth's own gain map (``max_j illum_j / illum_k``): scores 0 by construction."""
    return gain_from_illuminant(case.illum)


def weighted_average_gain(case: Case) -> np.ndarray:
    """The thesis' single white balance (§5.2: "a weighted average of the white points of existing
    illuminants is calculated and used for the whole image"), as the web explorer's baseline
    computes it (:func:`retarget.global_wb.frame_white_point`): the white points ``w_g`` weighted by
    each illuminant's mean mixture over the valid pixels,

    ``W̄ = Σ_g ω̄_g w_g``, ``ω̄_g = mean_{x ∈ mask} ω_g(x)``; the gain ``max_j W̄_j / W̄_k`` everywhere.
    """
    wp = global_wb.frame_white_point(case.mixture, case.mask, case.white_points)
    return gain_from_illuminant(np.broadcast_to(wp.astype(np.float32), (*case.shape, 3)))


ORACLES: dict[str, Callable[[Case], np.ndarray]] = {
    "Weighted Average": weighted_average_gain,
    "Ground Truth": ground_truth_gain,
}


def awb_gain_map(raw: np.ndarray, method: str = "Gray World", *, truth: Case | None = None,
                 valid: np.ndarray | None = None, **kwargs) -> np.ndarray:
    """The gain map ``(H, W, 3)`` float32 of ``method`` on raw ``(H, W, 3)``, colour-science style.

    method : a name of :data:`awb_eval.method_names.AWB_METHODS` (any case, aliases) or a plug-in
    ``module.path:callable``. truth : the ground truth, needed by the oracles. valid : pixels the
    statistics may use. kwargs : parameters of a statistical method (:func:`statistical_gain`).
    """
    if is_plugin(method):
        return check_gain(load_plugin(method)(np.asarray(raw, dtype=np.float32)), raw.shape[:2], method)
    name = AWB_METHODS.canonical(method)
    if name in ORACLES:
        if truth is None:
            raise SpectralError(f"AWB method {name!r} reads the ground truth: pass truth=")
        return ORACLES[name](truth)
    return statistical_gain(raw, name, valid=valid, **kwargs)


@dataclass(frozen=True)
class Method:
    """A method resolved once for a whole evaluation: ``label`` and ``run(case) → gain map``."""

    label: str
    run: Callable[[Case], np.ndarray]


def resolve(names: list[str], *, grid: tuple[int, int] | None = None, interpolation: str = "bilinear") -> list[Method]:
    """The methods to score, checked before anything is read: unknown names raise
    :class:`retarget.errors.UnknownName` (with close matches), bad plug-ins :class:`SpectralError`.
    ``grid``/``interpolation`` apply to the patch-wise methods."""
    out: list[Method] = []
    for raw_name in names:
        if is_plugin(raw_name):
            fn = load_plugin(raw_name)
            out.append(Method(raw_name, lambda c, fn=fn, n=raw_name: check_gain(_call_plugin(fn, c, n), c.shape, n)))
            continue
        name = AWB_METHODS.canonical(raw_name)
        if name in ORACLES:
            out.append(Method(name, ORACLES[name]))
        else:
            kw = {"grid": grid, "interpolation": interpolation} if name.startswith(PATCH_PREFIX) else {}
            out.append(Method(name, lambda c, n=name, kw=kw: statistical_gain(c.raw, n, valid=c.usable, **kw)))
    labels = [m.label for m in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise SpectralError(f"methods: {', '.join(repr(d) for d in dup)} named more than once (aliases count)")
    return out


def _call_plugin(fn: Callable, case: Case, spec: str) -> np.ndarray:
    try:
        return fn(case.raw.copy())  # a copy: a plug-in that writes into its input cannot change the next method's
    except Exception as exc:  # noqa: BLE001 — the user's code: one line, naming the image
        raise SpectralError(f"plug-in {spec!r} failed on {case.name}: {type(exc).__name__}: {exc}") from None


def check_gain(gain, shape: tuple[int, int], label: str) -> np.ndarray:
    """A plug-in's answer as a gain map ``(H, W, 3)`` float32: finite and positive, or a one-line error."""
    try:
        g = np.asarray(gain, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise SpectralError(f"plug-in {label!r} returned {type(gain).__name__}, not an array of gains ({exc})") from None
    if g.shape == (3,):
        g = np.broadcast_to(g, (*shape, 3))
    if g.shape != (*shape, 3):
        raise SpectralError(f"plug-in {label!r} returned shape {g.shape}; a gain map must be (H, W, 3) = "
                            f"{(*shape, 3)} (or (3,) for one gain)")
    bad = ~(np.isfinite(g) & (g > 0))
    if bad.any():
        raise SpectralError(f"plug-in {label!r} returned {int(bad.any(axis=-1).sum())} pixels with gains that are "
                            "not finite and positive; a gain map multiplies raw: every gain must be > 0")
    return np.ascontiguousarray(g)


def load_plugin(spec: str) -> Callable[[np.ndarray], np.ndarray]:
    """The callable named by ``module.path:callable`` (dots after the colon walk attributes).

    The current directory is searched too, so a model file beside the data can be named by its
    module name. Every failure is one :class:`SpectralError` line saying what to fix.
    """
    module_name, _, attr = spec.partition(":")
    module_name, attr = module_name.strip(), attr.strip()
    if not module_name or not attr:
        raise SpectralError(f"plug-in {spec!r}: write it as module.path:callable, e.g. mymodel:predict")
    added = os.getcwd() not in sys.path
    if added:
        sys.path.append(os.getcwd())
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name or module_name.startswith(f"{exc.name}."):
            raise SpectralError(f"plug-in {spec!r}: no module named {exc.name!r}; run from the directory that "
                                "holds it or add that directory to PYTHONPATH") from None
        raise SpectralError(f"plug-in {spec!r}: importing {module_name} failed: {exc}") from None
    except Exception as exc:  # noqa: BLE001 — the user's module: a syntax error, an import-time failure
        raise SpectralError(f"plug-in {spec!r}: importing {module_name} failed: {type(exc).__name__}: {exc}") from None
    finally:
        if added:
            sys.path.remove(os.getcwd())
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            names = [n for n in dir(obj) if not n.startswith("_")]
            close = difflib.get_close_matches(part, names, n=3, cutoff=0.6)
            hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
            raise SpectralError(f"plug-in {spec!r}: {module_name} has no attribute {part!r}{hint}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise SpectralError(f"plug-in {spec!r}: {attr} is a {type(obj).__name__}, not a callable raw → gain map")
    return obj
