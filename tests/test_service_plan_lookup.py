"""Planning a request that names its scene and view reads those, not the store's listing (a store
of thousands of generated scenes would otherwise list them on every request); unknown names are
still a 404 with close matches, and omitted ones are drawn from the listing."""

from __future__ import annotations

import pytest

from illumix.engine.context import make_context
from illumix.engine.errors import NotFound
from illumix.engine.sampling import plan
from illumix.engine.spec import SampleSpec
from illumix.store import CubeStore


@pytest.fixture(scope="module")
def ctx(tmp_path_factory):
    import synthetic_store

    path = tmp_path_factory.mktemp("plan") / "s"
    synthetic_store.build(path)
    return make_context(CubeStore.open(str(path), mode="r"), cache_mb=16)


def test_a_named_scene_and_view_are_not_looked_up_in_the_listing(ctx, monkeypatch):
    st = ctx.store

    def listing(*_a):
        raise AssertionError("listed the store for a named scene and view")

    monkeypatch.setattr(st, "scenes", listing)
    monkeypatch.setattr(st, "views", listing)
    p = plan(SampleSpec(scene="synth", view="v0", sensor="XYZ", pair="A,D65"), ctx)
    assert (p.scene, p.view) == ("synth", "v0")


@pytest.mark.parametrize("scene, view, match", [
    ("synht", "v0", "unknown scene 'synht'; did you mean 'synth'"),
    ("synth", "v9", "unknown view 'v9'"),
    ("../synth", "v0", "unknown scene '../synth'"),
    ("synth", "v0/..", "unknown view 'v0/..'"),
])
def test_unknown_or_unsafe_names_are_404s_with_close_matches(ctx, scene, view, match):
    with pytest.raises(NotFound, match=match):  # the service answers NotFound with 404
        plan(SampleSpec(scene=scene, view=view, sensor="XYZ", pair="A,D65"), ctx)


def test_omitted_names_are_drawn_from_the_listing(ctx):
    st = ctx.store
    p = plan(SampleSpec(sensor="XYZ", illuminants=None, seed=3), ctx)
    assert p.scene in st.scenes() and p.view in st.views(p.scene)
    assert plan(SampleSpec(sensor="XYZ", seed=3), ctx).view == p.view  # reproducible given the seed
    assert not st.has_scene("..") and not st.has_view("synth", "") and not st.has_view("nope", "v0")
