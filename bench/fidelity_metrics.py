"""What ``bench/fidelity.py`` measures on one corpus scene, from what ``/sample`` serves.

Every array comes from :class:`illumix_client.LocalClient` — the service's own composition, so a
number here is a number about ``GET /sample`` — for the two production stores (``P1``, ``P2``: the
same defaults, independent seeds) served by default (``D1``, ``D2``) and with ``denoise=none``
(``N1``, ``N2``), and for the reference store (``R``, ≥ 16× the paths, served as rendered).

- **Noise** of a production render per pixel and channel: ``σ² = box₅ₓ₅((N1 − N2)² / 2)`` (two
  independent renders; the 5×5 mean pools the single pair's one degree of freedom: 25 of them, so
  σ is under 0.6 of its value at 0.2 % of pixels; a 3×3 mean put the plain render's own false
  alarms at 0.66 %).
- **Bias** of the default: render 1's denoising operator (its guides and noise level, saved as it
  ran) applied to the reference's own cubes (``O``): ``b = O − R``, whose noise is only the
  reference's (σ/4, filtered); a pixel is *biased* when ``|b| > 3σ`` in any channel. Beside it,
  the same test on the two renders' mean, ``(D1 + D2)/2 − R``, with the plain render's
  ``(N1 + N2)/2 − R`` as that estimate's floor (its noise is ~0.75σ and heavy-tailed).
- **Mean shift**: per light group, the change of the frame's raw sum, default against
  ``denoise=none`` of the same render (a linear filter that moves light between pixels changes it).
- **Worse**: per pixel class, the mean squared relative error against ``R`` of the default and of
  ``denoise=none`` (render 1); a class is worse when the default's exceeds the plain render's
  (by more than 10⁻⁴ of it: pixels served as rendered are divided and multiplied back, float32).
- **R/G, B/G** (thesis eq. 4.1): per pixel of the composed raw, ``|(r/g)_served / (r/g)_R − 1|``,
  median and 99.3rd percentile over the lit surface (the ground-truth mask).

Requests: each group alone (``intensities`` one-hot, illuminant D65; outputs raw and the physical
illumination spectrum, reduced to three broad bands) and all groups together under distinct
illuminants (raw, illum, gain, mixture, weights, sRGB, mask) with a fixed exposure, so nothing
rescales.
"""

from __future__ import annotations

import numpy as np

SENSOR = "Nikon 5100 (NPL)"
MIX = ("A", "D65", "FL11", "D50", "F2")  # composite: one illuminant per group, in order
Z = 3.0  # the bias test's threshold, in σ
WORSE_MARGIN = 1e-4  # relative: a class served as rendered differs from the plain render by float32 rounding


def _box(a: np.ndarray, r: int = 2) -> np.ndarray:
    """(2r+1)² mean (edge replicated) of ``(H, W, C)``."""
    p = np.pad(a, ((r, r), (r, r), (0, 0)), mode="edge")
    h, w = a.shape[:2]
    k = 2 * r + 1
    return sum(p[i:i + h, j:j + w] for i in range(k) for j in range(k)) / float(k * k)


def _bands3(illum: np.ndarray) -> np.ndarray:
    """``(H, W, bands)`` → three broad-band sums (the illumination as a linear 3-channel image)."""
    n = illum.shape[-1]
    return np.stack([illum[..., k * n // 3:(k + 1) * n // 3].sum(-1) for k in range(3)], -1)


def requests(groups: list[str]) -> dict[str, dict]:
    """Request name → sample parameters (module docstring)."""
    out = {}
    for i, g in enumerate(groups):
        out[f"group:{g}"] = {"illuminants": ",".join(["D65"] * len(groups)),
                             "intensities": ",".join("1" if j == i else "0" for j in range(len(groups))),
                             "outputs": "raw,illumination,mask"}
    out["mix"] = {"illuminants": ",".join(MIX[k % len(MIX)] for k in range(len(groups))),
                  "outputs": "raw,illum,gain,mixture,weights,srgb,mask"}
    return out


def fetch(clients: dict, scene: str, view: str, groups: list[str]) -> dict:
    """``{request: {served: {output: array}}}`` for served in D1, D2, N1, N2, R and O (production 1's
    operator on the reference's cubes, served by default)."""
    plans = {"D1": ("P1", None), "D2": ("P2", None), "N1": ("P1", "none"), "N2": ("P2", "none"), "R": ("R", "none"),
             "O": ("O", None)}
    out: dict = {}
    for name, params in requests(groups).items():
        out[name] = {}
        for served, (store, dn) in plans.items():
            s = clients[store].sample(scene=scene, view=view, sensor=SENSOR, exposure="1", seed=0,
                                      **params, **({"denoise": dn} if dn else {}))
            arrays = {k: getattr(s, k) for k in ("raw", "illum", "gain", "mixture", "weights", "srgb", "mask")
                      if getattr(s, k, None) is not None}
            if getattr(s, "illumination", None) is not None:
                arrays["illumination"] = _bands3(s.illumination)
            out[name][served] = {k: np.asarray(v, np.float64) if k != "mask" else np.asarray(v, bool)
                                 for k, v in arrays.items()}
    return out


def bias_test(d1, d2, n1, n2, r, o, valid: np.ndarray) -> dict:
    """Biased pixels over ``valid``: ``biased`` from the operator on the reference (``o − r``: the
    bias alone, its noise the reference's σ/4 as filtered), and ``biased_two_renders`` from the two
    renders' mean (``(d1 + d2)/2 − r``, with the plain render's own count, ``biased_plain``, as that
    test's floor: heavy-tailed noise passes 3σ more often than a Gaussian)."""
    sigma = np.sqrt(_box((n1 - n2) ** 2 / 2.0))
    floor = 1e-6 * max(float(np.abs(r[valid]).max()) if valid.any() else 0.0, 1e-30)
    s = np.maximum(sigma, floor)
    alone = (np.abs(o - r) > Z * s).any(-1) & valid
    biased = (np.abs((d1 + d2) / 2 - r) > Z * s).any(-1) & valid
    plain = (np.abs((n1 + n2) / 2 - r) > Z * s).any(-1) & valid
    return {"pixels": int(valid.sum()), "biased": int(alone.sum()), "biased_two_renders": int(biased.sum()),
            "biased_plain": int(plain.sum()), "map": np.where(valid, (np.abs(o - r) / s).max(-1), 0.0)}


def pixel_classes(store_path: str, scene, view: str, ref_illum: np.ndarray) -> dict[str, np.ndarray]:
    """``{class: (H, W) bool}``: emitter, glass, glossy, edge, flat (each pixel in one, in that
    order of precedence; background in none). Edge: the view's ``straddle`` AOV, a geometric step
    (normal > 20° or depth > 5 % from a 4-neighbour's) or a light step (the reference's
    illumination changes by > 25 % to a 4-neighbour)."""
    from illumix.store import CubeStore

    st = CubeStore.open(store_path, mode="r")
    meta = st.view_meta(scene.name, view)
    aov = {n: st.read_aov(scene.name, view, n) for n in ("mask", "emitter", "normal", "depth", "straddle")
           if n in meta.aovs}
    hit = np.asarray(aov["mask"], bool)
    emitter = np.asarray(aov["emitter"], bool)
    glass, glossy = _material_kinds(scene, view, hit.shape)
    edge = np.asarray(aov.get("straddle", np.zeros_like(hit)), bool)
    n, d = np.asarray(aov["normal"], np.float64), np.log(np.maximum(np.asarray(aov["depth"], np.float64), 1e-3))
    lum = np.log(np.maximum(ref_illum.sum(-1), 1e-9 * max(float(ref_illum.sum(-1).max()), 1e-30)))
    for axis in (0, 1):
        for shift in (1, -1):
            nn, dd, ll = (np.roll(a, shift, axis) for a in (n, d, lum))
            edge |= ((n * nn).sum(-1) < 0.94) | (np.abs(d - dd) > 0.05) | (np.abs(lum - ll) > np.log(1.25))
    out, left = {}, hit.copy()
    for name, m in (("emitter", emitter), ("glass", glass & hit), ("glossy", glossy & hit), ("edge", edge & hit),
                    ("flat", hit)):
        out[name] = m & left
        left &= ~m
    return out


def _material_kinds(scene, view: str, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """``(glass, glossy)`` ``(H, W)`` bool from the first hit's BSDF at each pixel centre:
    transmission (glass), or a glossy or specular reflection lobe (plastic, metal)."""
    from illumix.renderer_jobs.mitsuba.trace import Tracer

    h, w = shape
    tr = Tracer(scene, view, None, (w, h))
    mi, dr = tr.mi, tr.dr
    pix = np.arange(w * h, dtype=np.int64)
    ray = tr._camera_rays(pix, np.full((w * h, 2), 0.5, np.float32), np.tile(np.float32([450, 550, 650, 550]),
                                                                                 (w * h, 1)), differential=False)
    si = tr.ms.ray_intersect(ray)
    flags = np.asarray(dr.select(si.is_valid(), si.bsdf(ray).flags(), 0), np.int64)
    F = mi.BSDFFlags
    trans = int(F.Transmission)
    refl = int(F.GlossyReflection) | int(F.DeltaReflection)
    return ((flags & trans) != 0).reshape(h, w), (((flags & refl) != 0) & ((flags & trans) == 0)).reshape(h, w)


def chroma_errors(served: np.ndarray, ref: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Relative R/G and B/G errors (%) of ``served`` against ``ref`` over ``valid``, flattened."""
    ok = valid & (served[..., 1] > 0) & (ref[..., 1] > 0)
    out = []
    for c in (0, 2):
        a = served[..., c][ok] / served[..., 1][ok]
        b = ref[..., c][ok] / ref[..., 1][ok]
        out.append(100 * np.abs(a / np.where(b > 0, b, np.nan) - 1))
    e = np.concatenate(out)
    return e[np.isfinite(e)]


def worse_by_class(d1: np.ndarray, n1: np.ndarray, r: np.ndarray, classes: dict) -> dict:
    """Per class: mean squared relative error (G-normalised) of the default and of the plain render."""
    scale = np.maximum(r[..., 1:2], 1e-3 * max(float(r[..., 1].max()), 1e-30))
    out = {}
    for name, m in classes.items():
        if m.sum() == 0:
            continue
        ed = float(np.mean(((d1 - r) / scale)[m] ** 2))
        en = float(np.mean(((n1 - r) / scale)[m] ** 2))
        # worse beyond float32 rounding: a pixel served as rendered is divided and multiplied back
        out[name] = {"pixels": int(m.sum()), "rmse_default_pct": 100 * ed ** 0.5, "rmse_plain_pct": 100 * en ** 0.5,
                     "worse": bool(ed > en * (1 + WORSE_MARGIN))}
    return out


def mean_shift_pct(d1: np.ndarray, n1: np.ndarray) -> float:
    """Largest change of a channel's frame sum, default against plain (%)."""
    s_d, s_n = d1.reshape(-1, d1.shape[-1]).sum(0), n1.reshape(-1, n1.shape[-1]).sum(0)
    ok = s_n > 0
    return float(100 * np.max(np.abs(s_d[ok] / s_n[ok] - 1))) if ok.any() else 0.0
