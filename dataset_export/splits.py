"""Train / validation / test splits by scene: no scene (so no room, no object arrangement) is in two
splits, which would leak its content from training into evaluation."""

from __future__ import annotations

import random
from collections.abc import Iterable, Sequence

from illumix.retarget.errors import SpectralError

SPLITS = ("train", "val", "test")


def parse_fractions(text: str) -> tuple[float, float, float]:
    """``"0.7,0.15,0.15"`` → train, val, test fractions (non-negative, summing to 1 within 1e-6)."""
    try:
        vals = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise SpectralError(f"--split {text!r}: give three numbers train,val,test, e.g. 0.7,0.15,0.15") from None
    if len(vals) != 3 or any(not (0 <= v <= 1) for v in vals) or abs(sum(vals) - 1) > 1e-6:
        raise SpectralError(f"--split {text!r}: need three fractions in [0, 1] summing to 1, e.g. 0.7,0.15,0.15")
    return vals  # type: ignore[return-value]


def split_counts(n: int, fractions: Sequence[float]) -> list[int]:
    """Scenes per split: largest remainder of ``n·fraction``, then every split with a non-zero fraction
    gets at least one scene while ``n`` allows (taken from the largest split)."""
    raw = [n * f for f in fractions]
    counts = [int(r) for r in raw]
    for i in sorted(range(len(raw)), key=lambda i: raw[i] - counts[i], reverse=True)[:n - sum(counts)]:
        counts[i] += 1
    for i, f in enumerate(fractions):
        if f > 0 and counts[i] == 0 and n >= sum(1 for x in fractions if x > 0):
            counts[max(range(len(counts)), key=counts.__getitem__)] -= 1
            counts[i] = 1
    return counts


def split_scenes(scenes: Iterable[str], fractions: Sequence[float], seed: int) -> dict[str, str]:
    """``{scene: split}``: the sorted scenes shuffled with ``seed``, then cut by :func:`split_counts`
    (deterministic in the scene set and the seed)."""
    order = sorted(set(scenes))
    random.Random(seed).shuffle(order)
    out, start = {}, 0
    for name, k in zip(SPLITS, split_counts(len(order), fractions)):
        for s in order[start:start + k]:
            out[s] = name
        start += k
    return out


def empty_split_warnings(by_split: dict[str, list[str]], fractions: Sequence[float], scenes: int) -> list[str]:
    """A warning (none or one) naming the splits given a non-zero fraction that hold no place as written
    (``by_split``: split → places): fewer scenes than the fractions need (splits are by scene, so a
    one-scene export has only a train split), or their places were all skipped."""
    empty = [name for name, f in zip(SPLITS, fractions) if f > 0 and not by_split.get(name)]
    if not empty:
        return []
    have = ", ".join(f"{k} {len(by_split.get(k, []))}" for k in SPLITS)
    keep = [f if name not in empty else 0.0 for name, f in zip(SPLITS, fractions)]
    first = next((i for i, f in enumerate(keep) if f > 0), 0)
    keep[first] += sum(fractions) - sum(keep)  # the empty splits' share moved to the first kept one
    names = " and ".join(empty)
    return [(f"the {names} split{'s are' if len(empty) > 1 else ' is'} empty (places per split: {have}; {scenes} "
             f"scene(s) for fractions {','.join(f'{f:g}' for f in fractions)}, split by scene): render more scenes, "
             f"or give --split with {names} 0 to mean it (e.g. --split {','.join(f'{f:g}' for f in keep)})")]
