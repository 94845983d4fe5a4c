"""The projection cache's request counts fade by halving (TinyLFU aging), lazily: what a count
reads is what halving every count each ``_AGE_EVERY`` requests gave, without the pause."""

from __future__ import annotations

import illumix.engine.projections as pj


def test_counts_halve_per_age_without_touching_every_key(monkeypatch):
    monkeypatch.setattr(pj, "_AGE_EVERY", 4)
    pc = pj.ProjectionCache(1 << 20)
    for _ in range(6):
        pc._count("a")  # 6 requests: one aging step after the 4th (a = 4 -> 2), then 3, 4
    assert pc._count("a") == 5  # 7th: counted before the second step (after the 8th)
    pc._count("b")  # the 8th request: a second aging step
    assert pc._aged(pc._seen["a"]) == 2  # 5 halved once
    for _ in range(8):  # two more steps: a untouched
        pc._count("c")
    assert pc._aged(pc._seen["a"]) == 0  # 2 -> 1 -> 0
    assert pc._count("a") == 1


def test_a_hot_key_outranks_a_faded_one_for_admission(monkeypatch):
    monkeypatch.setattr(pj, "_AGE_EVERY", 8)
    pc = pj.ProjectionCache(1 << 20)
    for _ in range(7):
        pc._count("old")
    for i in range(40):  # five aging steps: "old" fades to 0
        pc._count(("other", i % 2))
    assert pc._aged(pc._seen["old"]) == 0
    assert pc._count("new") > pc._aged(pc._seen["old"])
