"""Which light group gets which illuminant: the kinds of a view's groups and the rules of ``pair=``.

Group kinds
-----------
Each group of a view is ``daylight`` (sun, sky, windows), ``artificial`` (lamps) or unknown, from
what the store records, first match wins:

1. ``declared`` — the kind stored with the cube (:attr:`store.schema.CubeMeta.group_kind`, from the
   scene's ``light_groups[].kind`` or the scene model's inference from its emitters);
2. ``emission`` — the illuminant the cube was rendered with, when it names one
   (:func:`illuminant_kind`; ``flat`` and tabulated spectra say nothing);
3. ``name`` — the group's name has a daylight word in it (``daylight``, ``sun``, ``sunlight``,
   ``sky``, ``skylight``); the demo room's ``daylight`` group is one;
4. ``beside daylight`` — any other group of a view that has a daylight group is artificial.

A name such as ``window`` alone is *not* taken as daylight: stores in use name groups so (with
lamp-lit test data) and keep the order rule unless a kind is stored.

Pair rules
----------
- ``kind``: the view has daylight and artificial groups and exactly one illuminant of the pair is a
  daylight illuminant (:func:`illuminant_kind`): it lights every daylight group, the other
  illuminant every artificial group (groups of unknown kind stay off). The order in the pair does
  not matter then.
- ``order``: otherwise (no kinds, or both/neither illuminants daylight) the first illuminant lights
  the view's first group and the second its second; other groups stay off (the rule before kinds).

``illuminants=`` (one per group, in the view's order) is explicit and never reordered (``explicit``);
without either, every group is lit as rendered (``rendered``).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from illumix.retarget.errors import SpectralError

#: Above this correlated colour temperature an illuminant counts as daylight (unless named D-series).
DAYLIGHT_CCT_K = 4500.0
DAYLIGHT_WORDS = frozenset({"daylight", "sun", "sunlight", "sky", "skylight"})
KINDS = ("daylight", "artificial")
_D_SERIES = re.compile(r"^(?:I?D\d{2,3}|daylight:.*)$", re.IGNORECASE)

RULES = {
    "kind": "pair= by group kind: the pair's daylight illuminant lights the daylight groups, the other "
            "the artificial groups",
    "order": "pair= in order: the first illuminant lights the view's first group, the second its second, "
             "others off",
    "explicit": "illuminants=: one per group, in the view's group order",
    "rendered": "each group as rendered (D65 for flat emission, else its own emission)",
}


def cct(spd: np.ndarray, grid) -> float:
    """Correlated colour temperature (K) of band averages ``spd`` on ``grid`` (McCamy 1992, CIE 1931 2°)."""
    import colour

    xyz = _cmfs(grid).T @ np.asarray(spd, dtype=np.float64)
    total = float(xyz.sum())
    if not np.isfinite(total) or total <= 0:
        raise SpectralError("an illuminant without power has no colour temperature")
    return float(colour.temperature.xy_to_CCT(xyz[:2] / total, method="McCamy 1992"))


@lru_cache(maxsize=16)
def _cmfs(grid) -> np.ndarray:
    import colour

    from illumix.retarget.grid import resample

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return resample(cmfs.wavelengths, cmfs.values, grid, extend="zero")


def illuminant_kind(name: str | None, spd_of: Callable[[str], np.ndarray] | None = None, grid=None) -> str | None:
    """``daylight`` for CIE D-series names (D50…D75, ID50, ID65) and ``daylight:<K>``, else by CCT
    (``spd_of(name)`` on ``grid``) above :data:`DAYLIGHT_CCT_K`; ``artificial`` below; ``None`` for
    no name, ``flat``/``table``/files, or a name that cannot be resolved (refused later, by name)."""
    if not name or name in ("flat", "table") or name.lower().endswith(".csv"):
        return None
    if _D_SERIES.match(name):
        return "daylight"
    if spd_of is None or grid is None:
        return None
    try:
        return "daylight" if cct(spd_of(name), grid) > DAYLIGHT_CCT_K else "artificial"
    except (SpectralError, ValueError):
        return None


def name_kind(group: str) -> str | None:
    """``daylight`` when a word of the group's name is a daylight word (:data:`DAYLIGHT_WORDS`)."""
    return "daylight" if DAYLIGHT_WORDS & set(re.split(r"[^a-z]+", group.lower())) else None


def group_kinds(groups: list[str], metas: list, classify: Callable[[str], str | None]) -> list[tuple[str | None, str]]:
    """``(kind, source)`` per group (module docstring); ``classify``: :func:`illuminant_kind` of a name."""
    out: list[tuple[str | None, str]] = []
    for g, m in zip(groups, metas):
        declared = getattr(m, "group_kind", None)
        if declared in KINDS:
            out.append((declared, "declared"))
        elif (k := classify(m.emission_name) if m.emission_name != "flat" else None) is not None:
            out.append((k, "emission"))
        elif (k := name_kind(g)) is not None:
            out.append((k, "name"))
        else:
            out.append((None, "unknown"))
    if any(k == "daylight" for k, _ in out):
        out = [(k, s) if k is not None else ("artificial", "beside daylight") for k, s in out]
    return out


def pair_lighting(pair: list[str], kinds: list[str | None], classify: Callable[[str], str | None]
                  ) -> tuple[list[str | None], list[int | None], str, str]:
    """``(names per group, index in the pair per group (None: off), rule, why)`` of ``pair=``."""
    n = len(kinds)
    day = [classify(x) == "daylight" for x in pair]
    has_kinds = "daylight" in kinds and "artificial" in kinds
    if has_kinds and sum(day) == 1:
        d = day.index(True)
        which = [d if k == "daylight" else 1 - d if k == "artificial" else None for k in kinds]
        return [None if i is None else pair[i] for i in which], which, "kind", RULES["kind"]
    which = [0, 1] + [None] * (n - 2)
    if not has_kinds:
        why = "the view's groups have no known kinds (daylight and artificial)"
    else:
        why = f"{'both' if all(day) else 'neither'} of {pair[0]}, {pair[1]} {'are' if all(day) else 'is'} daylight"
    return [*pair, *[None] * (n - 2)], which, "order", f"{RULES['order']} ({why})"
