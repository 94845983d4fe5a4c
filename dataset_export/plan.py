"""Which places an export writes: (scene, view) pairs, each lit by one illuminant assignment.

A *place* is LSMI's unit (one scene as one camera saw it, under 1–3 lights): here a view of a scene
whose first ``k`` light groups are lit by ``k`` illuminants (a ``--pairs`` entry: ``k = 2``; an
``--illuminants`` entry: 1–3; LSMI has at most three lights). Views with fewer light groups than
the lighting needs are skipped, with the reason recorded. Each view takes the lightings that fit it in
a seeded order (no lighting twice). Without ``count`` every usable view is one place, lit by its
first; with it, ``count`` places are drawn: the views in a seeded order, round after round, each
round giving every view its next lighting (``<scene>-<view>-<n>`` for the ``n``-th repeat), so a
repeat is never a copy of a place already written. ``count`` beyond the distinct view × lighting
combinations yields each combination once (the export warns). The plan is a function of the
store's views, the options and the seed.
"""

from __future__ import annotations

import hashlib
import random
import re
from dataclasses import dataclass

from illumix.dataset_export.errors import ExportError

MAX_LIGHTS = 3  # LSMI's Light1..Light3


@dataclass(frozen=True)
class Place:
    """One place: ``name`` (no ``_``: LSMI splits file names ``<place>_<lights>`` on it), its
    ``scene``/``view``, the view's light ``groups`` (all, in order), ``lighting`` (the illuminants of
    its lights, LSMI's ``Light1..``) and a ``seed`` for its frames. ``pair``: the lighting is a
    ``--pairs`` entry, lit as ``/sample?pair=`` lights it (:mod:`engine.lighting`: the pair's daylight
    illuminant on the view's daylight groups, the other on its artificial ones where the groups have
    kinds, else the first two groups in order); otherwise light ``i`` is the view's group ``i``."""

    name: str
    scene: str
    view: str
    groups: tuple[str, ...]
    lighting: tuple[str, ...]
    seed: int
    pair: bool = False


def parse_lightings(pairs: str | None, illuminants: str | None) -> list[tuple[str, ...]]:
    """``--pairs "A,D65;FL11,D50"`` or ``--illuminants "A,D65,FL11;D50"`` → lightings (tuples of names).
    Neither: ``A,D65``."""
    if pairs and illuminants:
        raise ExportError("give either --pairs or --illuminants, not both")
    text, what = (pairs, "--pairs") if pairs else (illuminants or "A,D65", "--illuminants")
    out = []
    for item in text.split(";"):
        names = tuple(n.strip() for n in item.split(",") if n.strip())
        if not names:
            continue
        if what == "--pairs" and len(names) != 2:
            raise ExportError(f"--pairs: {item.strip()!r} is not two illuminants; write pairs as A,D65;FL11,D50")
        if len(names) > MAX_LIGHTS:
            raise ExportError(f"{what}: {item.strip()!r} has {len(names)} illuminants; LSMI places have at most "
                              f"{MAX_LIGHTS} lights")
        out.append(names)
    if not out:
        raise ExportError(f"{what}: no illuminants given; e.g. {what} A,D65")
    return out


def place_name(scene: str, view: str, rep: int) -> str:
    """A file-safe place name without ``_`` (``demo-room-0-front``; ``-<rep>`` for repeats)."""
    base = re.sub(r"[^A-Za-z0-9.-]+", "-", f"{scene}-{view}").strip("-.") or "place"
    return base if rep == 0 else f"{base}-{rep}"


def derive_seed(*parts: object) -> int:
    """A 63-bit seed from the export seed and names (stable across runs and Python versions)."""
    return int.from_bytes(hashlib.sha256(":".join(map(str, parts)).encode()).digest()[:8], "big") >> 1


def plan_places(views: list[tuple[str, str, tuple[str, ...]]], lightings: list[tuple[str, ...]], *,
                count: int | None, seed: int, pair: bool = False) -> tuple[list[Place], list[dict]]:
    """``(places, skipped)`` from the store's ``(scene, view, groups)`` (module docstring)."""
    need = min(len(lt) for lt in lightings)
    usable = sorted(v for v in views if len(v[2]) >= need)
    skipped = [{"scene": s, "view": v, "why": f"{len(g)} light group(s), the lighting needs {need}"}
               for s, v, g in sorted(views) if len(g) < need]
    if not usable:
        raise ExportError(f"no view of the store has the {need} light groups the lighting needs "
                          f"({len(views)} view(s) looked at); use --illuminants with fewer illuminants")
    rng = random.Random(seed)
    order = list(usable)
    if count is not None:
        rng.shuffle(order)
    unique = list(dict.fromkeys(lightings))  # the same lighting listed twice is one place, not two
    queues = []  # per view, its fitting lightings in a seeded order, taken one per round
    for _, _, groups in order:
        fitting = [lt for lt in unique if len(lt) <= len(groups)]
        rng.shuffle(fitting)
        queues.append(fitting)
    n = len(order) if count is None else min(count, sum(map(len, queues)))
    places, names = [], set()
    rep = 0
    while len(places) < n:
        for (scene, view, groups), queue in zip(order, queues):
            if len(places) == n or len(queue) <= rep:
                continue
            name = place_name(scene, view, rep)
            while name in names:  # two views whose names differ only in characters a file name cannot hold
                name += "x"
            names.add(name)
            places.append(Place(name, scene, view, tuple(groups), queue[rep], derive_seed(seed, name), pair))
        rep += 1
    return places, skipped
