"""Light groups of an imported scene and the spectrum each group is rendered with.

**Default rule** (no rule file, or emitters a rule file leaves to it): lights are grouped by kind and
colour temperature, so that an import gives mixed illuminants without any configuration —

- ``daylight``: environment maps, constant skies and directional (sun) lights (``kind: daylight``);
- ``warm``: every other emitter (area, point, spot) whose colour's correlated colour temperature is
  below :data:`WARM_BELOW_K` (incandescent, halogen, warm-white LEDs);
- ``cool``: the rest (neutral and cool white, daylight-balanced panels, uncoloured white).

An emitter given an exact spectrum (a ``λ:value`` table or a blackbody) keeps it: such emitters
share a group only with emitters of the same spectrum shape (``warm``, ``warm-2``, …). A rule file
(:mod:`scene_import.rules`) overrides all this: named groups first, then its ``default_group``, and
``grouping: each`` gives the old one-group-per-light behaviour.

**The group's spectrum** (:func:`group_emission`): a group with an environment map is ``flat`` (the
renderer draws the map's own RGB colours through Mitsuba's D65 upsampling and refuses anything
else); else a rule's illuminant; else the members' common exact spectrum (a table normalised to the
luminance of the flat unit spectrum — the emitter's strength carries its luminance, so strength ×
table is the source's spectrum — or ``blackbody:K``); else the CIE illuminant nearest the members'
mean chromaticity (:func:`scene_import.colour_match.illuminant_for`). Every member whose given colour
that does not reproduce (a coloured RGB, a spectrum replaced) gets a warning naming it and what it became.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from illumix.scene_import.colour_match import cct_duv, illuminant_for, uv_distance
from illumix.scene_import.names import Names

WARM_BELOW_K = 4000.0  # K: below it an emitter joins the warm group (incandescent ≈ 2700–3200 K)
DAYLIGHT_TYPES = ("envmap", "constant", "directional")
COLOUR_TOLERANCE_UV = 6e-3  # CIE 1960 Δuv beyond which a rule's illuminant misrepresents a member
WHITE_UV = 1e-3  # Δuv within which a white RGB (Mitsuba renders it as D65) is D65 exactly


@dataclass
class Emitter:
    """One light or emitting shape awaiting its group: ``doc`` gets ``group`` (lights) or
    ``emitter.group`` (shapes). ``names`` are matched by rules; ``key`` names a group of its own
    (``grouping: each``). ``xy``: its colour's chromaticity; ``spectrum``: an exact emission (an
    inline table dict, normalised, or ``"blackbody:K"``) when the file gave one; ``given``: how the
    file gave the colour, for warnings (``"rgb [1, 0.5, 0.2]"``)."""

    doc: dict
    names: list[str]
    key: str
    xy: np.ndarray | None
    what: str
    spectrum: dict | str | None = None
    given: str = ""

    @property
    def is_light(self) -> bool:
        return "group" in self.doc

    @property
    def type(self) -> str:
        return str(self.doc.get("type", "")) if self.is_light else "area"

    def set_group(self, g: str) -> None:
        (self.doc if self.is_light else self.doc["emitter"])["group"] = g


def spec_key(spec: dict | str | None) -> str | None:
    return None if spec is None else json.dumps(spec, sort_keys=True)


def default_bin(e: Emitter) -> str:
    """``daylight``, ``warm`` or ``cool`` (module docstring)."""
    if e.type in DAYLIGHT_TYPES:
        return "daylight"
    if e.xy is None:
        return "cool"
    cct, _ = cct_duv(e.xy)
    return "warm" if np.isfinite(cct) and cct < WARM_BELOW_K else "cool"


def assign(emitters: list[Emitter], rules, names: Names) -> dict[str, list[Emitter]]:
    """``{group name: members}`` in first-seen order: rules first, then the default rule."""
    members: dict[str, list[Emitter]] = {}
    by_key: dict[tuple, str] = {}
    each = rules is not None and rules.grouping == "each"
    if rules is not None:  # the rule file's names are kept exactly; default groups are named around them
        for g in [*(r.name for r in rules.groups), *([rules.default_group] if rules.default_group else [])]:
            names.used.add(g)
            by_key[("rule", g)] = g
    for e in emitters:
        rule = rules.group_for(e.names) if rules else None
        if rule is not None:
            k = ("rule", rule.name)
        elif rules is not None and rules.default_group:
            k = ("rule", rules.default_group)
        elif each:  # a light and an emissive material of the same name stay apart
            k = ("each", e.is_light, e.key)
        else:
            b = default_bin(e)
            k = ("bin", b, None if b == "daylight" else spec_key(e.spectrum))
        if k not in by_key:
            by_key[k] = names(k[1] if k[0] != "each" else k[2], "light")
        members.setdefault(by_key[k], []).append(e)
    return members


def group_emission(group: str, es: list[Emitter], named: str | None, warn) -> tuple[str | dict, str]:
    """``(emission, how it was chosen)`` of one group; warns for every member it misrepresents."""
    if any(e.type == "envmap" for e in es):
        if named:
            warn(f"light group {group!r}: has an environment map, which the renderer draws with its own "
                 f"colours (Mitsuba's D65 upsampling); the rule's illuminant {named} is not used")
        for e in es:
            if e.type != "envmap":
                _approximated(e, "D65 (Mitsuba's, as its environment map's group)", "D65", warn)
        return "flat", "flat: the environment map's own colours"
    if named:
        for e in es:
            if e.spectrum is not None or (e.xy is not None and uv_distance(e.xy, named) > COLOUR_TOLERANCE_UV):
                _approximated(e, f"{named} (the rule file's illuminant)", named, warn)
        return named, f"illuminant {named} from the rule file"
    keys = {spec_key(e.spectrum) for e in es}
    if len(keys) == 1 and es[0].spectrum is not None:
        spec = es[0].spectrum
        return spec, (spec if isinstance(spec, str) else "the spectrum given")
    xys = [e.xy for e in es if e.xy is not None]
    if not xys:
        return "D65", "D65: no colour given"
    emission, cct = illuminant_for(np.mean(xys, axis=0))
    for e in es:
        _approximated(e, f"{emission} (by colour temperature ~{cct:.0f} K)", emission, warn)
    return emission, f"{emission}, chosen by colour temperature ~{cct:.0f} K"


def _approximated(e: Emitter, became: str, emission: str, warn) -> None:
    """Warn unless the member's colour is exactly what ``emission`` renders (a white RGB as D65)."""
    if e.xy is None or (e.spectrum is not None and e.spectrum == emission):
        return
    d = uv_distance(e.xy, emission)
    if e.spectrum is None and emission == "D65" and d <= WHITE_UV:
        return  # a white (grey) RGB: Mitsuba's spectral RGB emission renders it as D65 too
    given = e.given or f"colour xy {np.round(e.xy, 4).tolist()}"
    warn(f"{e.what}: its emission ({given}) is approximated by {became}, Δuv {d:.4f}")
