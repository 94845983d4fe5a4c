"""Which group is lit by what (issue 38): pair= maps its daylight illuminant to daylight groups and the
other to artificial ones where the groups' kinds are known (declared, from the emission rendered with,
or a daylight name), else in order as before; illuminants= stays explicit; meta and the demo name
each group's illuminant and the rule."""

from __future__ import annotations

import numpy as np
import pytest

from illumix.engine.context import make_context
from illumix.engine.lighting import group_kinds, illuminant_kind, name_kind, pair_lighting
from illumix.engine.sampling import build_sample, plan
from illumix.engine.spec import SampleSpec
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID
from illumix.retarget.illuminants import illuminant_spd
from illumix.store import CubeMeta, CubeStore, ViewMeta

H, W = 12, 16
N = DEFAULT_GRID.n_bands


def _classify(name):
    return illuminant_kind(name, lambda n: illuminant_spd(n, DEFAULT_GRID), DEFAULT_GRID)


def _cube(level: float) -> np.ndarray:
    return np.full((H, W, N), level, np.float32)


def _write(st, scene: str, groups: dict[str, dict]) -> None:
    """View ``v`` of ``scene``: one flat cube per group; ``groups[g]``: extra CubeMeta fields."""
    st.write_view(scene, "v", ViewMeta(width=W, height=H, fov=45.0, groups=list(groups)))
    for k, (g, extra) in enumerate(groups.items()):
        st.write_cube(scene, "v", g, _cube(0.1 * (k + 1)),
                      CubeMeta(grid=DEFAULT_GRID.to_dict(), **({"emission_name": "flat"} | extra)))


@pytest.fixture(scope="module")
def ctx(tmp_path_factory):
    path = tmp_path_factory.mktemp("lighting") / "s"
    st = CubeStore.open(str(path), mode="a")
    _write(st, "demo", {"daylight": {}, "ceiling": {}, "desk": {}})  # the demo room's groups, no kinds stored
    _write(st, "legacy", {"window": {}, "lamp": {}})  # a store without kinds: the order rule
    _write(st, "declared", {"lamp": {"group_kind": "artificial"}, "window": {"group_kind": "daylight"}})
    _write(st, "generated", {"daylight": {"emission_name": "daylight:6200", "emission": [1.0] * N},
                             "pendant": {}})
    return make_context(CubeStore.open(str(path), mode="r"), cache_mb=16)


def _lit(p) -> dict:
    return dict(zip(p.groups, p.names))


# -- classification ------------------------------------------------------------------------------


@pytest.mark.parametrize("name, kind", [("A", "artificial"), ("D65", "daylight"), ("d50", "daylight"),
                                        ("daylight:5500", "daylight"), ("FL11", "artificial"),
                                        ("LED-B1", "artificial"), ("blackbody:6000", "daylight"),
                                        ("blackbody:3000", "artificial"), ("HP1", "artificial"),
                                        ("flat", None), ("no-such-light", None), (None, None)])
def test_illuminants_are_daylight_by_name_or_cct_above_4500k(name, kind):
    assert _classify(name) == kind


def test_group_kinds_follow_declared_then_emission_then_name():
    class M:
        def __init__(self, emission_name="flat", group_kind=None):
            self.emission_name, self.group_kind = emission_name, group_kind

    assert name_kind("daylight") == name_kind("sky_2") == name_kind("Sun") == "daylight"
    assert name_kind("window") is None and name_kind("sunday-lamp") is None
    demo = group_kinds(["daylight", "ceiling", "desk"], [M(), M(), M()], _classify)
    assert demo == [("daylight", "name"), ("artificial", "beside daylight"), ("artificial", "beside daylight")]
    assert group_kinds(["window", "lamp"], [M(), M()], _classify) == [(None, "unknown"), (None, "unknown")]
    got = group_kinds(["daylight", "tube"], [M(group_kind="artificial"), M("D65")], _classify)
    assert got == [("artificial", "declared"), ("daylight", "emission")]


def test_pair_rules_without_a_store():
    names, which, rule, _ = pair_lighting(["A", "D65"], ["daylight", "artificial", "artificial"], _classify)
    assert (names, which, rule) == (["D65", "A", "A"], [1, 0, 0], "kind")
    names, which, rule, why = pair_lighting(["A", "FL11"], ["daylight", "artificial"], _classify)
    assert (names, which, rule) == (["A", "FL11"], [0, 1], "order") and "neither" in why
    names, _, rule, why = pair_lighting(["A", "D65"], [None, None, None], _classify)
    assert (names, rule) == (["A", "D65", None], "order") and "no known kinds" in why


# -- through the engine ----------------------------------------------------------------------------


@pytest.mark.parametrize("pair", ["A,D65", "D65,A"])
def test_demo_groups_get_the_daylight_illuminant_on_daylight_in_either_order(ctx, pair):
    p = plan(SampleSpec(scene="demo", view="v", pair=pair, seed=1), ctx)
    assert _lit(p) == {"daylight": "D65", "ceiling": "A", "desk": "A"}
    assert p.intensities == [1.0, 1.0, 1.0] and p.lighting["rule"] == "kind"


def test_two_intensities_go_with_the_pairs_illuminants(ctx):
    p = plan(SampleSpec(scene="demo", view="v", pair="A,D65", intensities="0.25,2", seed=1), ctx)
    assert p.intensities == [2.0, 0.25, 0.25]
    p = plan(SampleSpec(scene="demo", view="v", pair="A,D65", intensities="1,0.5,0", seed=1), ctx)
    assert p.intensities == [1.0, 0.5, 0.0]  # one per group, as before
    with pytest.raises(SpectralError, match="one per illuminant of the pair"):
        plan(SampleSpec(scene="demo", view="v", pair="A,D65", intensities="1,1,1,1", seed=1), ctx)


def test_a_store_without_kinds_keeps_the_order_rule(ctx):
    p = plan(SampleSpec(scene="legacy", view="v", pair="A,D65", intensities="1,0.5", seed=1), ctx)
    assert _lit(p) == {"window": "A", "lamp": "D65"} and p.intensities == [1.0, 0.5]
    assert p.lighting["rule"] == "order"
    p = plan(SampleSpec(scene="demo", view="v", pair="A,FL11", seed=1), ctx)  # neither is daylight
    assert _lit(p) == {"daylight": "A", "ceiling": "FL11", "desk": None} and p.lighting["rule"] == "order"


def test_declared_and_emission_kinds_win(ctx):
    p = plan(SampleSpec(scene="declared", view="v", pair="daylight:5000,LED-B1", seed=1), ctx)
    assert _lit(p) == {"lamp": "LED-B1", "window": "daylight:5000"}
    p = plan(SampleSpec(scene="generated", view="v", pair="A,D50", seed=1), ctx)
    assert _lit(p) == {"daylight": "D50", "pendant": "A"}
    kinds = {g["group"]: (g["kind"], g["kind_from"]) for g in p.lighting["groups"]}
    assert kinds == {"daylight": ("daylight", "emission"), "pendant": ("artificial", "beside daylight")}


def test_illuminants_stay_explicit(ctx):
    p = plan(SampleSpec(scene="demo", view="v", illuminants="A,D65,FL11", seed=1), ctx)
    assert _lit(p) == {"daylight": "A", "ceiling": "D65", "desk": "FL11"} and p.lighting["rule"] == "explicit"


def test_meta_names_each_groups_illuminant_and_the_rule(ctx):
    _, meta = build_sample(SampleSpec(scene="demo", view="v", pair="A,D65", sensor="XYZ", seed=1,
                                      outputs="raw,meta"), ctx)
    assert [(i["group"], i["illuminant"]) for i in meta["illuminants"]] == [
        ("daylight", "D65"), ("ceiling", "A"), ("desk", "A")]
    rule = meta["lighting_rule"]
    assert rule["rule"] == "kind" and "daylight" in rule["why"]
    assert [(g["group"], g["kind"], g["illuminant"]) for g in rule["groups"]] == [
        ("daylight", "daylight", "D65"), ("ceiling", "artificial", "A"), ("desk", "artificial", "A")]


# -- scene, generator, store, demo ---------------------------------------------------------------


def test_scene_kinds_declared_or_from_emitters_and_not_in_the_hash():
    from illumix.scene.demo import demo_room
    from illumix.scene.load import scene_from_dict

    room = demo_room(0)
    assert [room.group_kind(g) for g in room.group_names] == ["daylight", "artificial", "artificial"]
    doc = room.model_dump(mode="json")
    for g in doc["light_groups"]:
        g.pop("kind")
    bare = scene_from_dict(doc, source="test")
    assert [bare.group_kind(g) for g in bare.group_names] == ["daylight", "artificial", "artificial"]  # emitters
    assert bare.scene_hash == room.scene_hash  # declaring kinds re-renders nothing
    doc["light_groups"][1]["kind"] = "daylight"
    assert scene_from_dict(doc, source="test").group_kind("ceiling") == "daylight"


def test_generated_rooms_declare_their_groups_kinds():
    from illumix.scenegen.generate import GeneratorConfig, generate_doc

    for seed in range(4):
        doc = generate_doc(seed, GeneratorConfig(probe=False))
        for g in doc["light_groups"]:
            assert g["kind"] == ("daylight" if g["name"] == "daylight" else "artificial"), (seed, g)


def test_cube_meta_group_kind_is_optional():
    old = CubeMeta.model_validate({"schema_version": 1, "grid": DEFAULT_GRID.to_dict()})
    assert old.group_kind is None
    assert CubeMeta(grid=DEFAULT_GRID, group_kind="daylight").group_kind == "daylight"
    with pytest.raises(ValueError):
        CubeMeta(grid=DEFAULT_GRID, group_kind="moonlight")


def test_demo_file_names_and_legend_name_each_groups_illuminant():
    from illumix.cmd_demo import _legend, _lit_label

    meta = {"illuminants": [{"group": "daylight", "illuminant": "daylight:5500", "intensity": 1.0},
                            {"group": "ceiling", "illuminant": "FL11", "intensity": 1.0},
                            {"group": "desk", "illuminant": None, "intensity": 0.0}],
            "lighting_rule": {"rule": "kind", "groups": [{"group": "daylight", "kind": "daylight"},
                                                         {"group": "ceiling", "kind": "artificial"},
                                                         {"group": "desk", "kind": "artificial"}]}}
    assert _lit_label(meta) == "daylight-daylight5500_ceiling-FL11"
    assert _legend(meta) == ("daylight (daylight) ← daylight:5500, ceiling (artificial) ← FL11, "
                             "desk (artificial) ← off [rule: kind]")
