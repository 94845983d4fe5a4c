"""Path guiding (issue 39, :mod:`renderer_jobs.mitsuba.path_guide`): the learnt field, its sampling
against its own pdf, unbiased renders (guided and plain agree within noise, transport and
illumination), less noise where light arrives only by a bounce, and the until-clean rule's
weighting of plain and guided rounds."""

from __future__ import annotations

import numpy as np
import pytest

from illumix.renderer_jobs.mitsuba import path_guide as pg
from illumix.renderer_jobs.mitsuba.until_clean import round_weights


def test_a_voxel_learns_where_its_light_came_from_and_an_unvisited_one_keeps_to_the_bsdf():
    lo, cell, dims = pg.grid_for(np.zeros(3), np.array([4.0, 2.0, 1.0]))
    padded = np.array([4.0, 2.0, 1.0]) + 0.08  # the bounds padded by 1 % of the longest side each side
    assert dims.tolist() == np.ceil(padded / (padded[0] / pg.GRID_MAX)).astype(int).tolist()
    assert dims[0] == pg.GRID_MAX and np.allclose(cell, padded[0] / pg.GRID_MAX)
    rng = np.random.default_rng(0)
    n = 4 * pg.MIN_RECORDS
    index = np.concatenate([np.full(n, 5 * pg.N_BINS + 17), 9 * pg.N_BINS + rng.integers(0, pg.N_BINS, n),
                            np.full(pg.MIN_RECORDS - 1, 11 * pg.N_BINS + 3), [-1]])
    value = np.concatenate([np.ones(n), rng.random(n), np.ones(pg.MIN_RECORDS - 1), [7.0]])
    f = pg.field_from_records(lo, cell, dims, index, value)
    assert f.pmf.shape == (int(np.prod(dims)) * pg.N_SIDES, pg.N_BINS) and np.allclose(f.pmf.sum(axis=1), 1, atol=1e-5)
    assert f.pmf[5, 17] == pytest.approx(1 - pg.UNIFORM_SHARE + pg.UNIFORM_SHARE / pg.N_BINS, rel=1e-5)
    assert f.pmf[5].min() == pytest.approx(pg.UNIFORM_SHARE / pg.N_BINS, rel=1e-5)  # no bin starved
    assert f.alpha[5] == pg.ALPHA and f.alpha[9] == pg.ALPHA
    assert f.alpha[11] == 0 and f.alpha[0] == 0 and f.guided_cells == 2  # too few records / none


mi = pytest.importorskip("mitsuba", reason="rendering needs the optional extra illumix[render]")


def test_sampled_directions_follow_the_pdf_the_guide_reports():
    """Directions drawn at a voxel: unit, their bins distributed as its pmf (χ² well within
    its 127 degrees of freedom), and the pdf returned with each equal to pdf() of it."""
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

    mi_, dr = import_mitsuba()
    rng = np.random.default_rng(1)
    lo, cell, dims = pg.grid_for(np.zeros(3), np.ones(3))
    pmf = rng.random((int(np.prod(dims)) * pg.N_SIDES, pg.N_BINS)) ** 4
    pmf /= pmf.sum(axis=1, keepdims=True)
    field = pg.GuideField(lo, cell, dims, pmf.astype(np.float32), np.full(len(pmf), 0.5, np.float32))
    g = pg.GuideArrays(mi_, dr, field)
    n, vox = 200_000, 37
    v = mi_.UInt32(np.full(n, vox, np.uint32))
    u = mi_.Float(rng.random(n, dtype=np.float32))
    u2 = mi_.Point2f(rng.random(n, dtype=np.float32), rng.random(n, dtype=np.float32))
    d, pdf = g.sample(v, u, u2, mi_.Bool(True))
    pdf2 = g.pdf(v, d, mi_.Bool(True))
    bins = np.asarray(g.bin_of(d))
    d_np = np.stack([np.asarray(d[i]) for i in range(3)], 1)
    np.testing.assert_allclose(np.linalg.norm(d_np, axis=1), 1, atol=1e-5)
    np.testing.assert_allclose(np.asarray(pdf), np.asarray(pdf2), rtol=1e-6)
    drawn = mi_.UInt32(np.asarray(g.bin_of(d)))
    same = np.isclose(np.asarray(pdf), pmf[vox][np.asarray(drawn)] * pg.N_BINS / (4 * np.pi), rtol=1e-5)
    assert same.mean() > 0.9995, same.mean()  # float rounding at a bin's edge may name its neighbour
    expected = pmf[vox] * n
    chi2 = float((((np.bincount(bins, minlength=pg.N_BINS) - expected) ** 2) / expected).sum())
    assert chi2 < 200, chi2
    # the pdf integrates to 1 over the sphere: its mean over uniform directions is 1/(4π)
    z, phi = rng.uniform(-1, 1, n), rng.uniform(-np.pi, np.pi, n)
    r = np.sqrt(1 - z * z)
    du = mi_.Vector3f(*(mi_.Float(x.astype(np.float32)) for x in (r * np.cos(phi), r * np.sin(phi), z)))
    assert float(np.mean(np.asarray(g.pdf(v, du, mi_.Bool(True))))) * 4 * np.pi == pytest.approx(1, rel=0.02)


def test_guided_and_inverse_variance_weights():
    """Rounds weigh by samples within their kind, and the kinds inversely to the variance of their
    halves: plain halves of s.d. 0.2, guided rounds of s.d. 0.2/√8 averaged 1:2 (variance (1/9 + 4/9)
    · 0.04/8), so the plain kind's share is (5/72) / (1 + 5/72) = 5/77; 1200 pixels estimate each
    variance to about 4 %."""
    rng = np.random.default_rng(2)

    def fake(spp, sd):
        h = 1 + rng.normal(0, sd, (30, 40, 2))
        return (None, None, {"samples_per_band_rendered": spp}, None, h)

    rounds = [fake(64, 0.2), fake(64, 0.2 / np.sqrt(8)), fake(128, 0.2 / np.sqrt(8))]
    w = round_weights(rounds, ["plain", "guided", "guided"])
    assert w.sum() == pytest.approx(1)
    assert w[1] / w[2] == pytest.approx(0.5)  # by samples within the guided kind
    assert w[0] == pytest.approx(5 / 77, abs=0.01)
    assert round_weights(rounds[:1], ["plain"]).tolist() == [1.0]


def _uplit_scene() -> dict:
    """A closed white room whose only light is a small panel just below the ceiling, facing it: the
    camera sees light that arrived by a bounce off the ceiling (plain paths find it by chance)."""
    from illumix.scene import demo

    walls = [("floor", (0, 0, 0), (0, 1, 0), (0, 0, -1)), ("ceiling", (0, 2, 0), (0, -1, 0), (0, 0, 1)),
             ("back", (0, 1, -1), (0, 0, 1), (0, 1, 0)), ("front", (0, 1, 1), (0, 0, -1), (0, 1, 0)),
             ("left", (-1, 1, 0), (1, 0, 0), (0, 1, 0)), ("right", (1, 1, 0), (-1, 0, 0), (0, 1, 0))]
    shapes = [{"name": n, "type": "rectangle", "material": "white",
               "transform": {"matrix": demo.frame_matrix(c, nrm, up, (2, 2))}} for n, c, nrm, up in walls]
    shapes.append({"name": "uplight", "type": "rectangle", "emitter": {"group": "lamp", "strength": 50.0},
                   "transform": {"matrix": demo.frame_matrix((0.5, 1.85, -0.5), (0, 1, 0), (0, 0, -1), (0.1, 0.1))}})
    return {"name": "uplit", "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.7}}},
            "shapes": shapes, "lights": [], "light_groups": [{"name": "lamp", "emission": "flat"}],
            "views": [{"name": "cam", "origin": (0, 1.0, 0.9), "target": (0, 0.7, -1), "fov": 70,
                       "resolution": (40, 30)}], "max_depth": 5}


def _render(scene, group: str, guided: bool, seed: int, spp: int = 32):
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission
    from illumix.renderer_jobs.render_settings import RenderSettings

    e = np.asarray(group_emission(scene, group)[0], np.float64)
    st = RenderSettings(denoise=None, seed=seed, spp=spp, clean_max_spp=0)
    return render_all_bands(scene, scene.views[0].name, [group], emitter_passes(scene, [group]), st, e, None, None,
                            "guided" if guided else "plain")


@pytest.fixture(scope="module")
def uplit():
    from illumix.scene.load import scene_from_dict

    return scene_from_dict(_uplit_scene())


def test_guided_renders_agree_with_plain_ones_within_noise_cube_and_illumination(uplit):
    """Two estimators of the same cube (guided: unbiased by its MIS weights), on a scene where the
    guide changes most paths: the image means agree within noise, the transport cube and the
    illumination cube (L/ρ of the first hit, and the white estimate), over 4 seeds each."""
    from test_render import assert_same_within_noise

    plain = [_render(uplit, "lamp", False, s) for s in range(1, 5)]
    guided = [_render(uplit, "lamp", True, s) for s in range(1, 5)]
    for k in (0, 1):  # cube, illumination cube
        a = np.mean([r[k] for r in plain], axis=0)
        b = np.mean([r[k] for r in guided], axis=0)
        assert_same_within_noise(a, b)
    assert guided[0][2]["guided"]["learnt"][0]["guided_cells"] > 0
    assert "guided" not in plain[0][2]
    assert guided[0][2]["nonfinite_samples"] == 0


def test_guiding_lowers_the_noise_where_light_arrives_by_a_bounce_and_is_deterministic(uplit):
    from illumix.renderer_jobs.clean_check import measure

    def rel(guided):
        a, b = (_render(uplit, "lamp", guided, s)[0].sum(-1) for s in (7, 8))
        return measure(a, b)["rel"]

    plain, guided = rel(False), rel(True)
    assert guided < 0.8 * plain, (plain, guided)
    one, two = _render(uplit, "lamp", True, 7), _render(uplit, "lamp", True, 7)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
