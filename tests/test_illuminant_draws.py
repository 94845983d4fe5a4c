"""Illuminant sampling beyond the Planckian locus (``--pairs draw:extended``): draws leave the locus
(Duv from colour-science, computed here from the SPDs), every draw is within the engine's
conditioning bounds through measured cameras, the pair's kinds are what ``pair=`` needs, and an
export with drawn pairs is readable with its SPD files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from illumix.dataset_export.illuminant_draws import FINE, draw_pair
from illumix.retarget.grid import DEFAULT_GRID

# colour-science says it extends a 380-780 nm SPD to its observer's 360-780 nm (zeros): expected here
pytestmark = pytest.mark.filterwarnings("ignore:Aligning:colour.utilities.ColourRuntimeWarning")

N_PLACES = 150  # 300 draws per sampling: ~12 % of extended ones leave the locus by |Duv| > 0.01


def _spd_fine(d) -> np.ndarray:
    """The drawn SPD on FINE (380–780 nm / 5 nm), a built-in name through colour-science itself."""
    import colour

    if not d.builtin:
        return d.samples
    kind, _, arg = d.name.partition(":")
    shape = colour.SpectralShape(380, 780, 5)
    if kind == "blackbody":
        return np.asarray(colour.sd_blackbody(float(arg), shape).values)
    if kind == "daylight":
        xy = colour.temperature.CCT_to_xy_CIE_D(float(arg) * 1.4388 / 1.4380)
        return np.asarray(colour.sd_CIE_illuminant_D_series(xy).align(shape).values)
    return np.asarray(colour.SDS_ILLUMINANTS[d.name].copy().align(shape).values)


def _duv(spd: np.ndarray) -> float:
    import colour

    sd = colour.SpectralDistribution(dict(zip(FINE, spd)))
    xyz = colour.sd_to_XYZ(sd, colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"])
    return float(colour.uv_to_CCT(colour.xy_to_UCS_uv(colour.XYZ_to_xy(xyz)), method="Ohno 2013")[1])


@pytest.fixture(scope="module")
def draws():
    return {s: [d for seed in range(N_PLACES) for d in draw_pair(seed, s, DEFAULT_GRID)]
            for s in ("planckian", "extended")}


def test_extended_draws_leave_the_planckian_locus(draws):
    duv = {s: np.array([_duv(_spd_fine(d)) for d in ds]) for s, ds in draws.items()}
    assert np.all(np.abs(duv["planckian"]) < 0.006)  # blackbodies (0) and CIE daylight (+0.003)
    off = np.abs(duv["extended"]) > 0.01
    assert off.mean() >= 0.08, f"only {off.mean():.0%} of extended draws are off the locus"
    families = {d.family for d in draws["extended"]}
    assert {"led", "fluorescent", "sky", "sun"} <= families and families & {"gel"}


def test_every_draw_passes_the_engines_conditioning_bounds(draws):
    """White-balance gain and CCM condition of every draw through XYZ and two measured cameras, each
    within retarget.conditioning's bounds (computed here with the bound's own definitions)."""
    from illumix.engine.library import DEFAULT_TRAINING_SET
    from illumix.retarget import conditioning as cond
    from illumix.retarget.ccm import fit_ccm
    from illumix.retarget.illuminants import spd_from_samples
    from illumix.retarget.reflectances import get_reflectances
    from illumix.retarget.sensors import get_sensor

    _, refl = get_reflectances(DEFAULT_TRAINING_SET, DEFAULT_GRID)
    sensors = [get_sensor(n, DEFAULT_GRID).weights() for n in ("XYZ", "Nikon 5100 (NPL)")]
    worst_gain = worst_cond = 0.0
    for d in draws["extended"][:120] + draws["planckian"][:40]:
        spd = spd_from_samples(FINE, _spd_fine(d), DEFAULT_GRID)
        for w in sensors:
            rgb = spd @ w
            worst_gain = max(worst_gain, rgb.max() / rgb.min())
            worst_cond = max(worst_cond, fit_ccm(w, spd, refl, DEFAULT_GRID).condition)
    assert worst_gain <= cond.MAX_WHITE_GAIN and worst_cond <= cond.MAX_CCM_CONDITION
    assert worst_gain < 100 and worst_cond < 100  # ordinary lights, far inside the bounds


def test_pairs_are_daylight_then_artificial_and_seeded(draws):
    from illumix.engine.lighting import DAYLIGHT_CCT_K, cct
    from illumix.retarget.illuminants import spd_from_samples

    ds = draws["extended"]
    for day, art in zip(ds[::2], ds[1::2]):
        assert cct(spd_from_samples(FINE, _spd_fine(day), DEFAULT_GRID), DEFAULT_GRID) > DAYLIGHT_CCT_K
        assert cct(spd_from_samples(FINE, _spd_fine(art), DEFAULT_GRID), DEFAULT_GRID) <= DAYLIGHT_CCT_K
    again = draw_pair(7, "extended", DEFAULT_GRID)
    assert [d.name for d in again] == [d.name for d in ds[14:16]]
    assert {"gel", "curtain", "sky", "sun"} <= {d.family for d in ds}


def test_export_with_drawn_pairs(tmp_path, capsys):
    pytest.importorskip("cv2")
    pytest.importorskip("pidng")
    from cli_testutil import run_cli
    from export_testutil import build_export_store

    store = build_export_store(tmp_path / "store")
    out = tmp_path / "o"
    code, _, err = run_cli(capsys, "export", store, str(out), "--pairs", "draw:extended", "--count", "8",
                           "--size", "32x24", "--seed", "5", "--noise", "none")
    assert code == 0, err
    meta = json.loads((out / "Nikon-5100-NPL" / "meta.json").read_text())
    manifest = json.loads((out / "manifest.json").read_text())["files"]
    names = [i["name"] for e in meta.values() for i in e["Illuminants"]]
    assert len(meta) == 8 and len(set(names)) > 8  # every place its own pair
    files = [n for n in names if n.endswith(".csv")]
    for n in files:  # a drawn SPD is a file of the export, in its manifest
        rel = n[len(str(out.resolve())) + 1:]
        assert rel.startswith("illuminants/") and rel in manifest
    assert "draw:extended" in (out / "README.md").read_text()
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "x"), "--pairs", "draw:rainbow")
    assert code == 2 and "draw:<sampling> takes planckian or extended" in err
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "y"), "--pairs", "draw:extended",
                           "--illuminants", "A")
    assert code == 2 and "not both" in err
