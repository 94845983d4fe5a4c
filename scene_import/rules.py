"""The light-group rule file: which imported lights and emissive materials form which light group.

YAML::

    groups:
      - name: ceiling
        match: ["Lamp*", "ceiling_*"]   # fnmatch patterns (case-insensitive) on light / emissive-material / node names
        illuminant: FL11                # optional: a named illuminant instead of the one chosen by CCT
        description: ceiling panels     # optional
      - name: window
        match: ["Sun", "Sky*"]
    default_group: other                # optional: lights no rule names (default: the default rule)
    grouping: kind                      # optional: "kind" (default) or "each" (one group per light)

An emitter joins the first group with a pattern matching any of its names (the source file's names
and the renderer-safe keys they became, e.g. ``Cube.001`` and ``Cube_001``). Without a rule file, or
for emitters no rule names when there is no ``default_group``, the default rule applies
(:mod:`scene_import.grouping`): ``daylight`` (environment, sky, sun), ``warm`` (other emitters below
4000 K) and ``cool`` (the rest), each with its own illuminant. ``grouping: each`` instead makes each
light — and each emissive material, with all its shapes — a group of its own, named after it.
Illuminant names are checked against :mod:`retarget.illuminants` (``F1``–``F12`` are accepted for
colour-science's ``FL1``–``FL12``).
"""

from __future__ import annotations

import fnmatch
import re
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator

from illumix.scene.spectra import Name, SceneError, StrictModel


class GroupRule(StrictModel):
    name: Name
    match: list[str] = Field(min_length=1)
    illuminant: str | None = None
    description: str = ""

    @field_validator("illuminant")
    @classmethod
    def _known(cls, v: str | None) -> str | None:
        if v is None:
            return v
        v = canonical_illuminant(v)
        from illumix.retarget.errors import SpectralError
        from illumix.retarget.illuminants import illuminant_spd

        try:
            illuminant_spd(v)
        except SpectralError as exc:
            raise ValueError(str(exc)) from None
        return v


class Rules(StrictModel):
    groups: list[GroupRule] = Field(default_factory=list)
    default_group: Name | None = None
    grouping: Literal["kind", "each"] = "kind"

    @field_validator("groups")
    @classmethod
    def _unique(cls, v: list[GroupRule]) -> list[GroupRule]:
        names = [g.name for g in v]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"duplicate group name(s) {', '.join(dup)}")
        return v

    def group_for(self, names: list[str]) -> GroupRule | None:
        """The first rule with a pattern matching any of ``names`` (case-insensitive fnmatch)."""
        low = [n.lower() for n in names if n]
        for g in self.groups:
            if any(fnmatch.fnmatchcase(n, p.lower()) for p in g.match for n in low):
                return g
        return None

    def illuminant(self, group: str) -> str | None:
        return next((g.illuminant for g in self.groups if g.name == group), None)

    def description(self, group: str) -> str:
        return next((g.description for g in self.groups if g.name == group), "")


def canonical_illuminant(name: str) -> str:
    """``F11`` → ``FL11`` (the CIE F-series as colour-science names it); other names unchanged."""
    m = re.fullmatch(r"[Ff](\d{1,2})", name.strip())
    return f"FL{m.group(1)}" if m else name.strip()


def load_rules(path: str | Path | None) -> Rules | None:
    """Read and validate a rule file; :class:`SceneError` with one line when it is bad."""
    if path is None:
        return None
    import yaml

    p = Path(path)
    if not p.is_file():
        raise SceneError(f"rule file {str(p)!r} does not exist")
    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        first = " ".join(str(exc).split())
        raise SceneError(f"{p}: not a valid YAML rule file: {first}") from None
    return rules_from_dict(doc or {}, source=str(p))


def rules_from_dict(doc, source: str = "rules") -> Rules:
    if not isinstance(doc, dict):
        raise SceneError(f"{source}: a rule file must be a mapping with 'groups' (and 'default_group')")
    try:
        return Rules.model_validate(doc)
    except ValidationError as exc:
        msgs = []
        for err in exc.errors():
            loc = ".".join(str(k) for k in err["loc"])
            msgs.append(f"{loc}: {err['msg'].removeprefix('Value error, ')}" if loc else err["msg"])
        raise SceneError(f"{source}: " + "; ".join(dict.fromkeys(msgs))) from None
