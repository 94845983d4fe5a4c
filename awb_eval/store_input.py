"""Evaluation cases composed from a cube store, by EXACTLY the service's pipeline.

Each case is ``engine.sampling.build_sample`` of a :class:`engine.spec.SampleSpec` (as ``GET
/sample`` and the client's local mode compose it): the raw, the GT illumination map, mixture, mask
and CCM map, and the per-group white points from the sample's metadata. Nothing is re-implemented.

The raw is what a camera records: exposed by the thesis' AEC (eq. 4.2, ``exposure=auto``: raw in
units of the white level) and clipped at the white level, so directly visible lamps and windows
saturate as they would, and the methods' statistics leave saturated pixels out
(:func:`awb_eval.case.unsaturated`). The ground truth does not depend on the exposure.

Which images: every view with enough light groups × every lighting in ``pairs`` (``"A,D65"`` is ``pair=``:
by group kind where the view's groups have kinds — the daylight illuminant on the daylight groups —
else the view's first two groups, :mod:`engine.lighting`; a single name ``"D65"`` lights every group with it),
optionally only ``count`` views drawn with ``seed``.
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from illumix.awb_eval.case import Case, Unusable, unsaturated
from illumix.engine.library import RANDOM
from illumix.retarget.errors import SpectralError

DEFAULT_SENSOR = "Nikon 5100 (NPL)"  # a measured camera that every install has (colour-science)
DEFAULT_PAIRS = ("A,D65", "FL11,D50")
OUTPUTS = ("raw", "illum", "mixture", "mask", "ccm", "meta")


def parse_pairs(text: str | None, default: tuple[str, ...] = DEFAULT_PAIRS) -> list[list[str]]:
    """``"A,D65;FL11,D50"`` → ``[["A", "D65"], ["FL11", "D50"]]``; one or two names per entry."""
    if text is None:
        return [p.split(",") for p in default]
    out = []
    for entry in str(text).split(";"):
        names = [n.strip() for n in entry.split(",") if n.strip()]
        if not names:
            continue
        if len(names) > 2:
            raise SpectralError(f"--pairs entry {entry.strip()!r} names {len(names)} illuminants; give one or two "
                                "per entry, entries separated by ';' (e.g. \"A,D65;FL11,D50\")")
        out.append(names)
    if not out:
        raise SpectralError(f"--pairs {text!r} names no illuminant; e.g. \"A,D65;FL11,D50\"")
    return out


@dataclass(frozen=True)
class Job:
    scene: str
    view: str
    lights: tuple[str, ...]
    sensor: str = ""

    @property
    def pair(self) -> str:
        return ",".join(self.lights)

    @property
    def name(self) -> str:
        return f"{self.scene}/{self.view} {self.pair}"


class StoreCases:
    """The cases of a store (module docstring); ``len()`` before anything is composed, then iterate."""

    kind = "store"

    def __init__(self, path: str, *, sensor: str | None = None, pairs: str | None = None, count: int | None = None,
                 seed: int = 0, size: str | None = None, gt: str | None = None, cache_mb: int = 1024) -> None:
        from illumix.engine.context import make_context
        from illumix.engine.local_library import LocalLibrary
        from illumix.store import CubeStore, StoreError

        try:
            self.store = CubeStore.open(path, mode="r")
        except StoreError as exc:
            raise SpectralError(f"store {path}: {exc}") from None
        self.path, self.sensor, self.seed, self.size, self.gt = path, sensor or DEFAULT_SENSOR, seed, size, gt
        self.ctx = make_context(self.store, cache_mb=cache_mb)
        self.ctx.library = LocalLibrary(self.store)  # sensors and illuminants also given by path, as elsewhere
        self.pairs = parse_pairs(pairs)
        views = [(s, v, len(self.store.groups(s, v))) for s in sorted(self.store.scenes())
                 for v in sorted(self.store.views(s))]
        views = [x for x in views if x[2] > 0]
        if not views:
            raise SpectralError(f"store {path} has no rendered views; render some with `illumix render`")
        self._check_names(views[0])
        if count is not None and count < len(views):
            views = sorted(random.Random(seed).sample(views, count))
        self.jobs = [Job(s, v, tuple(p)) for s, v, n in views for p in self.pairs if len(p) == 1 or n >= 2]
        self.jobs = [Job(j.scene, j.view, j.lights, self._sensor(k)) for k, j in enumerate(self.jobs)]
        if not self.jobs:
            raise SpectralError(f"store {path}: no view has the two light groups a pair needs (views: "
                                f"{', '.join(f'{s}/{v}' for s, v, _ in views[:5])}); give single illuminants, "
                                "e.g. --pairs D65")
        self.skipped = len(views) * len(self.pairs) - len(self.jobs)
        self.spec(self.jobs[0])  # bad options fail here, not as every image skipped

    def _sensor(self, k: int) -> str:
        """``--sensor random``: each image its own camera drawn from the prior, ``random:<seed + k>``."""
        return f"{RANDOM}:{self.seed + k}" if self.sensor.strip().lower() == RANDOM else self.sensor

    def _check_names(self, first: tuple[str, str, int]) -> None:
        """Unknown sensor or illuminant → one line with close matches, before any composition."""
        grid = self.store.cube_meta(first[0], first[1], self.store.groups(first[0], first[1])[0]).spectral_grid
        self.ctx.library.sensor(self._sensor(0), grid)
        for name in {n for p in self.pairs for n in p}:
            self.ctx.library.illuminant(name, grid)

    def __len__(self) -> int:
        return len(self.jobs)

    def describe(self) -> dict:
        return {"kind": self.kind, "path": self.path, "sensor": self.sensor, "pairs": [",".join(p) for p in self.pairs],
                "views": len({(j.scene, j.view) for j in self.jobs}), "images": len(self.jobs),
                "skipped_single_group": self.skipped, "seed": self.seed, "size": self.size, "gt": self.gt}

    def __iter__(self) -> Iterator[Case | Unusable]:
        """The cases in order; a view the service cannot compose as asked (its groups cannot be
        relit, lack the illumination cubes ``--gt physical`` needs, a damaged cube …) is an
        :class:`Unusable` with the service's reason, not the end of the run."""
        for job in self.jobs:
            try:
                yield self.compose(job)
            except SpectralError as exc:
                yield Unusable(job.name, job.pair, str(exc))

    def spec(self, job: Job):
        """The :class:`engine.spec.SampleSpec` of ``job``; the run's options (size, gt …) are
        checked here, with one line for a bad one."""
        from pydantic import ValidationError

        from illumix.engine.spec import SampleSpec

        n_groups = len(self.store.groups(job.scene, job.view))
        light = {"pair": list(job.lights)} if len(job.lights) == 2 else {"illuminants": list(job.lights) * n_groups}
        try:
            return SampleSpec(scene=job.scene, view=job.view, sensor=job.sensor, seed=self.seed, size=self.size,
                              gt=self.gt, outputs=list(OUTPUTS), exposure="auto", **light)
        except ValidationError as exc:
            first = exc.errors()[0]
            raise SpectralError(f"{'.'.join(str(x) for x in first.get('loc', ()))}: {first.get('msg')}") from None

    def compose(self, job: Job) -> Case:
        """One sample through :func:`engine.sampling.build_sample` → a :class:`Case`."""
        from illumix.engine.errors import Busy
        from illumix.engine.sampling import build_sample
        from illumix.store import StoreError

        spec = self.spec(job)
        try:
            arrays, meta = build_sample(spec, self.ctx)
        except Busy as exc:
            raise SpectralError(str(exc)) from None  # the image is named beside it (Unusable)
        except StoreError as exc:
            raise SpectralError(f"store problem: {exc}; run `illumix store verify`") from None
        lit = [i for i, g in enumerate(meta["illuminants"]) if g["illuminant"] is not None and g["intensity"] > 0]
        wps = np.array([meta["illuminants"][i]["white_point_rgb"] for i in range(len(meta["illuminants"]))])
        raw = np.minimum(arrays["raw"], np.float32(1))  # the white level
        return Case(name=job.name, pair=job.pair, raw=raw, illum=arrays["illum"], mask=arrays["mask"],
                    mixture=arrays["mixture"][..., lit], white_points=wps[lit], ccm=arrays["ccm"],
                    usable=unsaturated(raw, 1.0), sensor=meta["sensor"]["name"])
