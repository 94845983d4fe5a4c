"""Random sample specs for training: which view, lit how, seen by which sensor, cut where.

Pure numpy, no I/O and no torch: :class:`SpecSampler` turns a ``numpy.random.Generator`` into one
``/batch`` item. :class:`illumix_client.torch_dataset.IllumixDataset` seeds that generator from
``(seed, epoch, index)`` so every item is reproducible and independent of worker layout.

Illuminant pools
----------------
An entry is either a name the service knows (``"A"``, ``"D65"``, ``"FL11"``, ``"LED-B3"``,
``"blackbody:3200"``, an uploaded name) or a *range* ``"blackbody:2500-7500"`` /
``"daylight:4000-10000"`` (kelvin, drawn uniformly and rounded to ``cct_step`` K so the service's
per-illuminant caches stay warm). Each light group draws one entry uniformly from its pool, then a
temperature if the entry is a range. A pool is a list of entries, a single entry, or a mapping from
group name to pool with ``"*"`` for every other group (``{"window": "daylight:5000-9000",
"*": CIE_STANDARD}``).
"""

from __future__ import annotations

import fnmatch
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Union

import numpy as np

CIE_STANDARD = ("A", "D50", "D55", "D65", "D75")
CIE_FLUORESCENT = tuple(f"FL{i}" for i in range(1, 13))
CIE_LED = ("LED-B1", "LED-B2", "LED-B3", "LED-B4", "LED-B5", "LED-BH1", "LED-RGB1", "LED-V1", "LED-V2")

_RANGE = re.compile(r"^\s*(blackbody|daylight)\s*:\s*(\d+(?:\.\d*)?)\s*[-–]\s*(\d+(?:\.\d*)?)\s*[kK]?\s*$")

Pool = Union[str, Sequence[str]]


@dataclass(frozen=True)
class ViewInfo:
    """One view of the store as GET /scenes lists it."""

    scene: str
    view: str
    width: int
    height: int
    groups: tuple[str, ...]
    emissions: tuple[str | None, ...] = ()

    @property
    def key(self) -> str:
        return f"{self.scene}/{self.view}"


def views_from_scenes(scenes: Sequence[Mapping[str, Any]]) -> list[ViewInfo]:
    """Flatten GET /scenes into :class:`ViewInfo` rows, sorted by ``scene/view`` (views the service
    lists as ``damaged`` are left out: they cannot be served)."""
    out = []
    for s in scenes:
        for v in s["views"]:
            if v.get("damaged"):
                continue
            groups = tuple(g["name"] for g in v["groups"])
            out.append(ViewInfo(s["name"], v["name"], int(v["width"]), int(v["height"]), groups,
                                tuple(g.get("emission") for g in v["groups"])))
    return sorted(out, key=lambda v: v.key)


def select_views(views: Sequence[ViewInfo],
                 include: str | Sequence[str] | Callable[[ViewInfo], bool] | None = None,
                 *, min_groups: int = 1, crop: tuple[int, int] | None = None) -> list[ViewInfo]:
    """Views that match ``include`` (``"scene"``, ``"scene/view"`` or fnmatch patterns such as
    ``"kitchen-*"``, or a predicate), have at least ``min_groups`` light groups and are at least as
    large as ``crop`` ``(w, h)``."""
    if include is None:
        keep: Callable[[ViewInfo], bool] = lambda v: True  # noqa: E731
    elif callable(include):
        keep = include
    else:
        pats = [include] if isinstance(include, str) else list(include)

        def keep(v: ViewInfo) -> bool:
            return any(fnmatch.fnmatchcase(v.key if "/" in p else v.scene, p) for p in pats)

    out = [v for v in views if keep(v) and len(v.groups) >= min_groups]
    if crop is not None:
        out = [v for v in out if v.width >= crop[0] and v.height >= crop[1]]
    return out


@dataclass(frozen=True)
class _Entry:
    name: str | None = None           # a fixed illuminant
    kind: str | None = None           # "blackbody" | "daylight" for a range
    lo: float = 0.0
    hi: float = 0.0


def parse_entry(entry: str) -> _Entry:
    """``"D65"`` → fixed; ``"blackbody:2500-7500"`` → a range (kelvin, lo ≤ hi)."""
    if not isinstance(entry, str) or not entry.strip():
        raise ValueError(f"illuminant pool entries are names or ranges, got {entry!r}")
    m = _RANGE.match(entry)
    if not m:
        return _Entry(name=entry.strip())
    lo, hi = float(m[2]), float(m[3])
    if not 0 < lo <= hi:
        raise ValueError(f"illuminant range {entry!r}: need 0 < low <= high kelvin")
    return _Entry(kind=m[1], lo=lo, hi=hi)


class IlluminantPool:
    """Draws one illuminant name per light group (see the module docstring for the forms)."""

    def __init__(self, pool: Pool | Mapping[str, Pool], cct_step: float = 50.0) -> None:
        if cct_step <= 0:
            raise ValueError("cct_step must be > 0 kelvin")
        self.cct_step = float(cct_step)
        mapping = dict(pool) if isinstance(pool, Mapping) else {"*": pool}
        self.pools: dict[str, tuple[_Entry, ...]] = {}
        for group, p in mapping.items():
            entries = (p,) if isinstance(p, str) else tuple(p)
            if not entries:
                raise ValueError(f"illuminant pool for {group!r} is empty")
            self.pools[group] = tuple(parse_entry(e) for e in entries)

    def entries(self) -> list[_Entry]:
        return [e for p in self.pools.values() for e in p]

    def for_group(self, group: str) -> tuple[_Entry, ...]:
        if group in self.pools:
            return self.pools[group]
        if "*" in self.pools:
            return self.pools["*"]
        raise ValueError(f"no illuminant pool for light group {group!r}; add a '*' entry")

    def draw_one(self, rng: np.random.Generator, group: str) -> str:
        pool = self.for_group(group)
        e = pool[int(rng.integers(len(pool)))]
        if e.name is not None:
            return e.name
        k = float(rng.uniform(e.lo, e.hi))
        k = min(max(round(k / self.cct_step) * self.cct_step, e.lo), e.hi)
        return f"{e.kind}:{k:g}"

    def draw(self, rng: np.random.Generator, groups: Sequence[str], distinct: bool = True) -> list[str]:
        """One name per group; with ``distinct`` a group redraws (at most 8 times) to differ from the
        groups before it, so mixtures are mixtures where the pool allows."""
        names: list[str] = []
        for g in groups:
            name = self.draw_one(rng, g)
            for _ in range(8 if distinct else 0):
                if name not in names:
                    break
                name = self.draw_one(rng, g)
            names.append(name)
        return names


def _pair(value: int | Sequence[int] | None, what: str) -> tuple[int, int] | None:
    if value is None:
        return None
    w, h = (value, value) if isinstance(value, (int, np.integer)) else tuple(value)
    if int(w) <= 0 or int(h) <= 0:
        raise ValueError(f"{what} must be positive (w, h) pixels, got {value!r}")
    return int(w), int(h)


class SpecSampler:
    """Draws /batch items. ``crop`` ``(w, h)`` (or an int for a square) is placed uniformly inside the
    frame; ``size`` ``(W, H)`` resamples after the crop; ``intensity_range`` ``(lo, hi)``: each group's
    intensity ~ U(lo, hi), then all are divided by their maximum (the brightest group is 1, the
    others carry the ratio); ``sensors`` is drawn uniformly."""

    def __init__(self, views: Sequence[ViewInfo], illuminants: IlluminantPool, sensors: Sequence[str],
                 *, intensity_range: tuple[float, float] = (0.25, 1.0), crop=None, size=None,
                 outputs: Sequence[str] = ("raw", "gain", "mask"), exposure: str | float | None = None,
                 noise: str | Mapping[str, float] | None = None, bayer: str | None = None,
                 distinct: bool = True, gt: str | None = None, denoise: str | None = None,
                 dtype: str | None = None) -> None:
        if not views:
            raise ValueError("no views to draw from (check the scene filter, min_groups and crop size)")
        if not sensors or isinstance(sensors, str):
            raise ValueError("sensors must be a non-empty list of names, e.g. ['XYZ']")
        lo, hi = (float(x) for x in intensity_range)
        if not 0 < lo <= hi:
            raise ValueError(f"intensity_range needs 0 < lo <= hi, got {intensity_range!r}")
        self.views, self.pool, self.sensors = list(views), illuminants, list(sensors)
        self.intensity_range = (lo, hi)
        self.crop, self.size = _pair(crop, "crop"), _pair(size, "size")
        self.outputs = [o for o in outputs if o != "meta"] + ["meta"]
        self.exposure, self.noise, self.bayer, self.distinct, self.gt = exposure, noise, bayer, distinct, gt
        self.denoise, self.dtype = denoise, dtype

    def spec(self, rng: np.random.Generator) -> dict[str, Any]:
        """One /batch item (a dict of :data:`illumix_client.sample.SPEC_KEYS`)."""
        v = self.views[int(rng.integers(len(self.views)))]
        names = self.pool.draw(rng, v.groups, self.distinct)
        lo, hi = self.intensity_range
        a = rng.uniform(lo, hi, size=len(v.groups))
        a = a / a.max()
        spec: dict[str, Any] = {
            "scene": v.scene, "view": v.view, "seed": int(rng.integers(2**31 - 1)),
            "sensor": self.sensors[int(rng.integers(len(self.sensors)))],
            "illuminants": names, "intensities": [round(float(x), 6) for x in a],
            "outputs": self.outputs,
        }
        if self.gt is not None:
            spec["gt"] = self.gt
        if self.crop is not None:
            w, h = self.crop
            spec["crop"] = [int(rng.integers(v.width - w + 1)), int(rng.integers(v.height - h + 1)), w, h]
        if self.size is not None:
            spec["size"] = list(self.size)
        for k in ("exposure", "noise", "bayer", "denoise", "dtype"):
            if getattr(self, k) is not None:
                spec[k] = getattr(self, k)
        return spec
