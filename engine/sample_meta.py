"""The metadata of a composed sample (``meta`` in every answer): what was composed, how, from what."""

from __future__ import annotations

import numpy as np

from illumix.engine import extra_outputs as extra
from illumix.retarget import conditioning as cond

#: The bounds every served pair is within (:mod:`retarget.conditioning`), stated beside the values.
CONDITIONING_LIMITS = {"max_white_balance_gain": cond.MAX_WHITE_GAIN,
                       "max_ccm_condition_number": cond.MAX_CCM_CONDITION}


def sample_meta(p, sensor, white_points, ccms, quality, mask, valid, reasons, exposure_gain, noise, timings) -> dict:
    """The sample's metadata (module docstring); ``quality``: per group the
    :class:`retarget.conditioning.Conditioning` of its sensor × illuminant, or None (not fitted)."""
    spec, grid = p.spec, p.metas[0].spectral_grid
    meta = {
        "scene": p.scene, "view": p.view, "groups": p.groups, "seed": p.seed,
        "sensor": {"name": sensor.name, "source": sensor.source},
        "illuminants": [
            {"group": g, "illuminant": n, "intensity": a,
             "white_point_rgb": [float(v) for v in wp],
             "ccm": None if c is None else np.asarray(c).round(8).tolist()} | _quality(q, c is not None)
            for g, n, a, wp, c, q in zip(p.groups, p.names, p.intensities, white_points,
                                         ccms if ccms is not None else [None] * len(p.groups), quality)
        ],
        "lighting_rule": p.lighting,
        "conditioning_limits": CONDITIONING_LIMITS,
        "ground_truth": {"method": p.gt, "why": p.gt_why, "equations": GT_EQUATIONS[p.gt]},
        "denoise": _denoise_meta(p),
        "mask_reasons": {"meaning": extra.MASK_REASONS,
                         "pixels": reasons | ({"no_light": int(np.count_nonzero(~mask)) - sum(reasons.values())}
                                              if mask is not None and valid is not None else {})},
        "crop": list(p.window), "size": list(p.out_size), "exposure_gain": exposure_gain,
        "noise": None if noise is None else noise.__dict__ | {"seed": p.seed}, "bayer": p.bayer,
        "grid": grid.to_dict(),
        "provenance": [{"group": g, "emission": m.emission_name, "renderer": m.renderer.model_dump(),
                        "spp": m.spp, "seed": m.seed, "scene_hash": m.scene_hash, "created": m.created,
                        "empty": m.empty,
                        "denoised": None if m.denoised is None else m.denoised.model_dump(
                            include={"method", "params", "cost_ms"})} for g, m in zip(p.groups, p.metas)],
        "timings_ms": timings,
    }
    return meta


def _quality(q, served: bool) -> dict:
    """What ``meta`` states of a group's CCM: its real fit error (CIEDE2000 mean and max over the training
    set, of the matrix as served) and its condition number, with the white-balance gain its white point
    implies; nulls where no CCM is served. Each is within the bounds of :mod:`retarget.conditioning`
    (:data:`CONDITIONING_LIMITS`), or the sample would have been refused."""
    fields = dict.fromkeys(("ccm_fit_delta_e00_mean", "ccm_fit_delta_e00_max", "ccm_condition_number",
                            "white_balance_gain"))
    return fields | (q.meta() if q is not None and served else {})


def _denoise_meta(p) -> dict:
    """``{method, why, params, guides, linear, reference}`` of what was read (params of the first lit group)."""
    out = {"method": p.denoise, "why": p.denoise_why}
    if p.denoise != "none":
        dn = next(m.denoised for m, r in zip(p.metas, p.reads()) if r)
        out |= dn.model_dump(include={"params", "guides", "linear", "reference"})
    return out


GT_EQUATIONS = {
    "physical": "U_k = sum_g sum_i C_k (a Phi/E)_g U_g dlambda (relit illumination cubes); illum = U/U_G; "
                "mixture_g = U_{g,G}/U_G; gain_k = max_j U_j/U_k; ccm = sum_g mixture_g CCM_g",
    "formula": "w_g = R_{g,G}/sum_h R_{h,G} (thesis eq. 3.3); illum = sum_g w_g wp_g; gain_k = max_j illum_j/illum_k; "
               "ccm = sum_g w_g CCM_g",
}
