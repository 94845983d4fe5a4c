"""The minimum mixed-light fraction of a kept view (scenegen.views.MixedLightRule): measured on a
synthetic probe (hand-made per-group luminance, no renderer), checked pixel by pixel here."""

from __future__ import annotations

import sys
import types
from types import SimpleNamespace

import numpy as np
import pytest

from illumix.scenegen.views import (
    MixedLightRule,
    apply_rule,
    probe_views,
    two_group_fraction,
)


def _by_hand(y: np.ndarray, share: float) -> np.ndarray:
    """The rule's fraction with plain loops: per pixel, the light of each group over the total."""
    g, v, h, w = y.shape
    out = []
    for k in range(v):
        valid = mixed = 0
        for i in range(h):
            for j in range(w):
                light = [float(y[n, k, i, j]) for n in range(g)]
                total = sum(light)
                if total <= 0:
                    continue
                valid += 1
                mixed += sum(x > share * total for x in light) >= 2
        out.append(mixed / valid if valid else 0.0)
    return np.array(out)


def test_two_group_fraction_against_a_hand_count():
    rng = np.random.default_rng(4)
    y = rng.gamma(0.6, size=(3, 4, 9, 11)).astype(np.float32)
    y[:, 1, :4] = 0  # dark rows: not valid, not counted
    y[1:, 2] = 0.01 * y[1:, 2]  # one group dominates everywhere
    for share in (0.05, 0.2, 0.35):
        np.testing.assert_allclose(two_group_fraction(y, share), _by_hand(y, share), atol=1e-12)
    assert two_group_fraction(y[:1], 0.2).tolist() == [0.0] * 4  # one group: never mixed


def _fake_probe(monkeypatch, images: dict[str, list[np.ndarray]]):
    """Replace the Mitsuba probe by per-group luminance images ``{group: [image per view]}``."""
    fake = types.ModuleType("illumix.renderer_jobs.mitsuba.view_probe")
    fake.group_luminance = lambda scene, views, g, resolution, spp: np.stack(images[g])
    monkeypatch.setitem(sys.modules, "illumix.renderer_jobs.mitsuba.view_probe", fake)


def test_views_below_the_minimum_are_dropped_with_the_reason(monkeypatch):
    h, w = 12, 16
    one = np.ones((h, w), np.float32)
    half = one.copy()
    half[:, w // 2:] = 0  # the lamp reaches the left half only
    images = {"window": [one, one, one, one], "lamp": [one, 0.04 * one, half, 0.5 * one]}
    _fake_probe(monkeypatch, images)
    scene = SimpleNamespace(views=[SimpleNamespace(name=f"view{i}") for i in range(4)],
                            group_names=["window", "lamp"])
    res = probe_views(scene)  # the default rule: 30 % of the pixels, two groups above 20 % each
    assert MixedLightRule() == MixedLightRule(min_fraction=0.3, min_share=0.2)
    # view0 all mixed; view1 a "screen" at 4 % of the light; view2 mixed on (about) its left half,
    # the 3x3 blur of the probe widening the lit band by one column; view3 lamp at 1/3 of the light
    np.testing.assert_allclose(res.two_group, [1.0, 0.0, (w // 2 + 1) / w, 1.0])
    assert res.keep.tolist() == [True, False, True, True]
    assert res.why == [("view view1: 0% of its pixels have two light groups above 20% of the light (at least 30% "
                        "needed); dropped")]
    strict = probe_views(scene, rule=MixedLightRule(min_fraction=0.6))
    assert strict.keep.tolist() == [True, False, False, True] and len(strict.why) == 2
    off = probe_views(scene, rule=MixedLightRule(min_fraction=0.0))
    assert off.keep.all() and not off.why
    # the older probe() answers as before from the same luminance
    from illumix.scenegen.views import probe

    frac, shares = probe(scene)
    np.testing.assert_allclose(frac, res.mixed)
    np.testing.assert_allclose(shares[1], [1 / 1.04, 0.04 / 1.04], rtol=1e-6)


def test_rule_is_validated():
    from pydantic import ValidationError

    for bad in ({"min_fraction": 1.5}, {"min_share": 0.0}, {"min_share": 0.7}, {"fraction": 0.3}):
        with pytest.raises(ValidationError):
            MixedLightRule(**bad)
    keep, why = apply_rule(["a", "b"], np.array([0.29, 0.3]), MixedLightRule())
    assert keep.tolist() == [False, True] and len(why) == 1 and why[0].startswith("view a: 29%")


def test_dataset_summary_counts_dropped_views():
    """`illumix dataset` sums what generated rooms record of dropped views (generator.views_dropped)."""
    from illumix.cmd_dataset import views_dropped

    scenes = [SimpleNamespace(generator={"name": "illumix.scenegen", "views_dropped": 3}),
              SimpleNamespace(generator={"name": "illumix.scenegen"}), SimpleNamespace(generator=None),
              SimpleNamespace(generator={"views_dropped": 1})]
    assert views_dropped(scenes) == 4


def _stand_in_probe(monkeypatch, two_group):
    """Generation with a stand-in probe: every candidate clear, the given two-group fractions."""
    import illumix.scenegen.views as views
    from illumix.scenegen.views import ViewProbe, apply_rule

    def probe(scene, views=None, rule=None):
        names = [v.name for v in scene.views]
        two = np.resize(np.asarray(two_group, float), len(names))
        keep, why = apply_rule(names, two, rule)
        return ViewProbe(names, mixed=two.copy(), shares=np.full((len(names), 2), 0.5), two_group=two,
                         keep=keep, why=why)

    monkeypatch.setattr(views, "probe_views", probe)
    monkeypatch.setattr(views, "clear_views", lambda scene, names, resolution=None: np.ones(len(names), bool))


def test_generated_rooms_keep_only_views_the_rule_keeps(monkeypatch, tmp_path):
    from illumix.scenegen.generate import GeneratorConfig, generate_doc

    monkeypatch.setenv("ILLUMIX_CACHE", str(tmp_path))
    _stand_in_probe(monkeypatch, [0.1, 0.5, 0.05, 0.4])  # every other candidate below 0.3
    cfg = GeneratorConfig(candidates=8, views=(3, 3))
    doc = generate_doc(11, cfg)
    assert len(doc["views"]) == 3 and doc["generator"]["views_dropped"] == 4
    assert doc["generator"]["mixed_light_rule_met"] is True
    assert "0.50" in doc["description"] and "0.05" not in doc["description"].split("per view")[1]


def test_a_room_with_no_mixed_view_keeps_its_best_and_says_so(monkeypatch, tmp_path):
    from illumix.scenegen.generate import GeneratorConfig, generate_doc

    monkeypatch.setenv("ILLUMIX_CACHE", str(tmp_path))
    _stand_in_probe(monkeypatch, [0.1, 0.2, 0.05, 0.15])
    with pytest.warns(UserWarning, match="no candidate view has 30% .*kept the most mixed one \\(20%\\)"):
        doc = generate_doc(11, GeneratorConfig(candidates=4, views=(3, 3)))
    assert len(doc["views"]) == 1 and doc["generator"]["mixed_light_rule_met"] is False
    assert doc["generator"]["views_dropped"] == 4
    off = generate_doc(11, GeneratorConfig(candidates=4, views=(3, 3), mixed_light={"min_fraction": 0.0}))
    assert len(off["views"]) == 3 and off["generator"]["views_dropped"] == 0
