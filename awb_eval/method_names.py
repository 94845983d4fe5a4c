"""The AWB method family by name, the colour-science way (``method="Gray World"``).

Pure Python, like :mod:`retarget.denoise_methods`: ``illumix evaluate --help`` lists these names
before numpy is imported. The implementations are in :mod:`awb_eval.methods`; every method answers
a per-pixel white-balance gain map ``(H, W, 3)``.

Besides these names, a method may be a plug-in ``module.path:callable`` (see
:func:`awb_eval.methods.load_plugin`): a name with a colon is always read as one.
"""

from __future__ import annotations

from illumix.retarget.registry import MethodRegistry

#: Global statistical methods (one illuminant for the whole image) and their aliases. Each has a
#: patch-wise twin named ``"Patch " + name`` (aliases likewise).
GLOBAL_METHODS = {
    "Gray World": "mean of each channel (Buchsbaum 1980): e = (Σ f)/N; van de Weijer et al. 2007 e^{0,1,0}",
    "White Patch": "maximum of each channel, max-RGB (Land 1977): e = max f; e^{0,∞,0}",
    "Shades of Gray": "Minkowski p-norm of each channel (Finlayson & Trezzi 2004), p = 6: e^{0,6,0}",
    "Gray Edge": "Minkowski norm of the gradient magnitude of the Gaussian-smoothed image (van de Weijer, "
                 "Gevers & Gijsenij 2007, eq. 10), n = 1, p = 1, σ = 6 px: e^{1,1,6}",
    "2nd Order Gray Edge": "as Gray Edge on the 2nd-order derivatives √(f_xx² + 4 f_xy² + f_yy²) "
                           "(van de Weijer et al. 2007), n = 2, p = 1, σ = 1 px: e^{2,1,1}",
}
GLOBAL_ALIASES = {
    "Grey World": "Gray World", "GW": "Gray World",
    "max-RGB": "White Patch", "MaxRGB": "White Patch", "WP": "White Patch",
    "Shades of Grey": "Shades of Gray", "SoG": "Shades of Gray",
    "Grey Edge": "Gray Edge", "GE1": "Gray Edge", "1st Order Gray Edge": "Gray Edge",
    "2nd Order Grey Edge": "2nd Order Gray Edge", "GE2": "2nd Order Gray Edge",
    "Second Order Gray Edge": "2nd Order Gray Edge",
}
PATCH_PREFIX = "Patch "

#: Methods that read the ground truth: the thesis' baseline and the sanity row.
ORACLE_METHODS = {
    "Weighted Average": "the thesis' single white point (§5.2): the illuminants' white points weighted by their "
                        "mean mixture over the valid pixels, W̄ = Σ_g mean_x(ω_g) w_g, applied to the whole image "
                        "(reads the ground truth)",
    "Ground Truth": "the ground-truth gain map itself (a sanity row: scores 0)",
}
ORACLE_ALIASES = {"WA": "Weighted Average", "Average White Point": "Weighted Average",
                  "Single White Point": "Weighted Average", "GT": "Ground Truth", "Oracle": "Ground Truth"}


def _patchwise() -> tuple[dict[str, str], dict[str, str]]:
    names = {PATCH_PREFIX + n: f"{n} per cell of a grid (default 4×4), cell estimates bilinearly interpolated "
                               "between cell centres (the patch-wise use of the thesis §5.2 and LSMI's baselines)"
             for n in GLOBAL_METHODS}
    aliases = {PATCH_PREFIX + a: PATCH_PREFIX + t for a, t in GLOBAL_ALIASES.items()}
    return names, aliases


_PATCH, _PATCH_ALIASES = _patchwise()

#: name → one-line description of every built-in AWB method.
AWB_METHODS: MethodRegistry[str] = MethodRegistry(
    "AWB method", {**GLOBAL_METHODS, **_PATCH, **ORACLE_METHODS},
    aliases={**GLOBAL_ALIASES, **_PATCH_ALIASES, **ORACLE_ALIASES})

#: What ``illumix evaluate`` scores unless told otherwise.
DEFAULT_METHODS = (*GLOBAL_METHODS, "Patch Gray World", "Weighted Average", "Ground Truth")


def is_plugin(name: str) -> bool:
    """A method spelled ``module.path:callable`` (a user's model), not a built-in name."""
    return ":" in name


def split_methods(text: str) -> list[str]:
    """``"Gray World, GE1 ,pkg.mod:fn"`` → ``["Gray World", "GE1", "pkg.mod:fn"]`` (empty items dropped)."""
    return [m.strip() for m in str(text).split(",") if m.strip()]
