"""Test cubes, the float64 reference and the error metrics of ``bench/pareto.py``.

Test cube (render-free, for when no rendered store is given): a two-group room-like view whose
materials are *measured* reflectances — the 99 CIE 224:2017 colour-fidelity samples and the 24
ColorChecker patches (``retarget.reflectances``) — in Voronoi regions, some regions a smooth blend
of two samples (texture), a 4×6 ColorChecker chart; per group smooth shading (window gradient /
lamp 1/r²) with soft shadows down to ~1e-3, a spatially varying inter-reflection tint by a
coloured wall's reflectance (transport ``ρ(x,λ)·(1 + α(x)(ρ_wall(λ)/mean − 1))``: a product of
spectra, so higher spectral rank than the reflectances alone), directly visible emitters (flat
spectra, 10³× and 50× the mean), rows no light reaches, and Monte-Carlo-like noise: log-normal
per band and pixel with relative std ``noise`` plus rare fireflies (×30).

Reference: the same composition as :func:`retarget.compose.compose` (DESIGN.md equations), written
out independently in float64 on the float32 render output (before any storage): per-group raw by
a float64 matmul, weights / gain map / CCM map in float64, the constant AEC of eq. 4.2 and the
sRGB transfer function in float64.
"""

from __future__ import annotations

import numpy as np

from illumix.retarget import groundtruth as gt
from illumix.retarget.exposure import AECParams
from illumix.retarget.metrics import angular_error, delta_e00, grid_delta_e00
from illumix.retarget.reflectances import get_reflectances
from illumix.retarget.relight import band_scales

GROUPS = ("window", "lamp")


def _smooth(rng: np.random.Generator, h: int, w: int, coarse: tuple[int, int] = (5, 7)) -> np.ndarray:
    """Smooth random field in [0, 1] ``(h, w)``: bilinear upsampling of a coarse random grid."""
    c = rng.uniform(0.0, 1.0, coarse)
    ys, xs = np.linspace(0, coarse[0] - 1, h), np.linspace(0, coarse[1] - 1, w)
    y0 = np.minimum(ys.astype(int), coarse[0] - 2)
    x0 = np.minimum(xs.astype(int), coarse[1] - 2)
    ty, tx = (ys - y0)[:, None], (xs - x0)[None, :]
    top = c[y0][:, x0] * (1 - tx) + c[y0][:, x0 + 1] * tx
    bot = c[y0 + 1][:, x0] * (1 - tx) + c[y0 + 1][:, x0 + 1] * tx
    return top * (1 - ty) + bot * ty


def _voronoi(rng: np.random.Generator, h: int, w: int, n: int) -> np.ndarray:
    """Region labels ``(h, w)`` int: nearest of ``n`` random seeds (computed at 1/4 resolution)."""
    ch, cw = max(1, h // 4), max(1, w // 4)
    pts = rng.uniform(0, 1, (n, 2)) * [ch, cw]
    yy, xx = np.mgrid[0:ch, 0:cw].astype(np.float32)
    d = (yy[..., None] - pts[:, 0]) ** 2 + (xx[..., None] - pts[:, 1]) ** 2
    lab = np.argmin(d, axis=-1)
    return np.repeat(np.repeat(lab, 4, axis=0), 4, axis=1)[:h, :w] if h >= 4 and w >= 4 else \
        np.zeros((h, w), int)


def reflectance_image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """``(h, w, 63)`` float32 reflectances from measured sets (see module docstring)."""
    pool = np.concatenate([get_reflectances("CIE 2017")[1], get_reflectances("ColorChecker N Ohta")[1]])
    n_reg = 80
    lab = _voronoi(rng, h, w, n_reg)
    a = rng.integers(0, len(pool), n_reg)
    b = rng.integers(0, len(pool), n_reg)
    blend = np.where(rng.uniform(0, 1, n_reg) < 0.35, rng.uniform(0.3, 1.0, n_reg), 0.0)
    alpha = (blend[lab] * _smooth(rng, h, w, (12, 16)))[..., None]
    refl = (pool[a][lab] * (1 - alpha) + pool[b][lab] * alpha).astype(np.float32)
    cc = get_reflectances("ColorChecker N Ohta")[1].astype(np.float32)
    p = max(1, min(h // 14, w // 20))
    y0, x0 = h // 2, w // 2
    for i in range(24):
        r, c = divmod(i, 6)
        refl[y0 + r * p: y0 + (r + 1) * p - max(1, p // 8), x0 + c * p: x0 + (c + 1) * p - max(1, p // 8)] = cc[i]
    return refl


def _shadows(rng: np.random.Generator, u: np.ndarray, v: np.ndarray, n: int, depth: float) -> np.ndarray:
    out = np.ones_like(u)
    for _ in range(n):
        sx, sy, r = rng.uniform(0.1, 0.9), rng.uniform(0.3, 0.95), rng.uniform(0.05, 0.15)
        d = np.sqrt((u - sx) ** 2 + ((v - sy) * 1.4) ** 2) / r
        out *= 1 - (1 - depth) / (1 + np.exp(np.minimum((d - 1) * 10, 60)))
    return out


def test_cubes(h: int, w: int, noise: float, seed: int = 0) -> list[np.ndarray]:
    """Two transport cubes ``[window, lamp]``, each ``(h, w, 63)`` float32 ≥ 0 (flat unit emission)."""
    rng = np.random.default_rng(seed)
    refl = reflectance_image(rng, h, w)
    pool = get_reflectances("CIE 2017")[1]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    u, v = xx / w, yy / h
    shade = {
        "window": 0.02 + 1.5 * (1 - u) ** 2 * (0.6 + 0.4 * _smooth(rng, h, w)),
        "lamp": 0.02 + 0.06 / ((u - 0.75) ** 2 + (v - 0.15) ** 2 + 0.03),
    }
    cubes = []
    for g in GROUPS:
        s = (shade[g] * _shadows(rng, u, v, 3, 1e-3)).astype(np.float32)
        wall = pool[rng.integers(0, len(pool))]
        tint = (wall / wall.mean() - 1).astype(np.float32)
        alpha = (0.35 * _smooth(rng, h, w)).astype(np.float32)
        cube = refl * s[..., None] * (1 + alpha[..., None] * tint)
        ey, ex = int(0.1 * h), int((0.7 if g == "lamp" else 0.05) * w)
        eh, ew = max(2, h // 30), max(2, w // 25)
        cube[ey:ey + eh, ex:ex + ew] = 1e3 if g == "lamp" else 50.0  # directly visible emitter (flat)
        other = (0.05 if g == "lamp" else 0.7) * w
        cube[ey:ey + eh, int(other):int(other) + ew] *= 1e-2  # the other group's emitter barely lit
        cube[-max(1, h // 50):] = 0.0  # rows no light reaches (mask False)
        if noise > 0:
            sig = np.float32(np.sqrt(np.log1p(noise ** 2)))
            for r0 in range(0, h, 64):
                blk = cube[r0:r0 + 64]
                z = rng.standard_normal(blk.shape, dtype=np.float32)
                blk *= np.exp(sig * z - sig * sig / 2)
                blk[rng.random(blk.shape, dtype=np.float32) < 1e-4] *= 30
        cubes.append(np.ascontiguousarray(cube, dtype=np.float32))
    return cubes


# --------------------------------------------------------------------------------- reference


def _group_raw64(cube: np.ndarray, m: np.ndarray) -> np.ndarray:
    h, w, b = cube.shape
    flat = cube.reshape(h * w, b)
    out = np.empty((h * w, 3))
    for s in range(0, h * w, 1 << 16):
        out[s:s + (1 << 16)] = flat[s:s + (1 << 16)].astype(np.float64) @ m
    return out.reshape(h, w, 3)


def reference(cubes: list[np.ndarray], *, emissions: np.ndarray, illuminants: np.ndarray,
              intensities: np.ndarray, sensor, ccms: np.ndarray, rel_eps: float = gt.DEFAULT_REL_EPS
              ) -> dict[str, np.ndarray]:
    """Float64 composition: ``raw``, ``gain``, ``srgb`` ``(H, W, 3)``, ``mask`` ``(H, W)``."""
    scales = band_scales(illuminants, emissions, intensities)
    sw = np.asarray(sensor.weights(), np.float64)
    group_raw = np.stack([_group_raw64(c, scales[g][:, None] * sw) if intensities[g] > 0
                          else np.zeros(c.shape[:2] + (3,)) for g, c in enumerate(cubes)])
    raw = group_raw.sum(axis=0)
    green = np.clip(group_raw[..., 1], 0, None)
    total = green.sum(axis=0)
    mask = total > max(rel_eps * total.max(), np.finfo(np.float64).tiny)
    fallback = green[:, mask].sum(axis=1) / total[mask].sum()
    weights = np.where(mask[None], green / np.where(mask, total, 1.0)[None], fallback[:, None, None])
    weights = np.moveaxis(weights, 0, -1)
    lit = intensities > 0
    wps = np.ones((len(illuminants), 3))
    wps[lit] = gt.white_points(sw, illuminants[lit])
    white = weights @ wps
    gain = white.max(axis=-1, keepdims=True) / white
    ccm = (weights @ np.asarray(ccms, np.float64).reshape(len(ccms), 9)).reshape(*raw.shape[:2], 3, 3)
    lin = np.einsum("hwij,hwj->hwi", ccm, raw * gain)
    p = AECParams()
    m_cur, h_cur = lin.mean(), np.percentile(lin, p.h_percentile)
    exposure = min(max(m_cur * p.h_target / h_cur, p.m_min), p.m_max) / m_cur if m_cur > 0 and h_cur > 0 else 1.0
    x = np.clip(lin * exposure, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return {"raw": raw, "gain": gain, "srgb": srgb, "mask": mask, "group_raw": group_raw}


def block_mean(img: np.ndarray, f: int) -> np.ndarray:
    """Area downscale by an integer factor ``f`` (what cv2's INTER_AREA does for integer factors)."""
    h, w = img.shape[0] // f * f, img.shape[1] // f * f
    x = img[:h, :w].astype(np.float64)
    return x.reshape(h // f, f, w // f, f, *img.shape[2:]).mean(axis=(1, 3))


# ----------------------------------------------------------------------------------- metrics


def errors(out: dict[str, np.ndarray], ref: dict[str, np.ndarray], de_sample: int = 1 << 17,
           seed: int = 0) -> dict[str, float]:
    """Errors of a composition against the reference.

    gain: angular error (deg) of the gain vectors on the reference's valid pixels, max and p99.
    raw: ``|R − R_ref| / max(R_ref, 1e-6 · max R_ref)`` per pixel and channel, max and p99 (the
    floor keeps the no-light rows, where both are ~0, from dividing by zero).
    sRGB: per-pixel CIEDE2000 p99 and max on up to ``de_sample`` random pixels (plus the grid
    ΔE00 score of thesis appendix B on the whole image).
    """
    mask = ref["mask"]
    ang = angular_error(out["gain"][mask], ref["gain"][mask]) if mask.any() else np.zeros(1)
    r = ref["raw"]
    floor = max(1e-6 * float(r.max()), np.finfo(np.float64).tiny)
    rel = np.abs(out["raw"].astype(np.float64) - r) / np.maximum(np.abs(r), floor)
    a, b = out["srgb"].reshape(-1, 3), ref["srgb"].reshape(-1, 3)
    if a.shape[0] > de_sample:
        idx = np.random.default_rng(seed).choice(a.shape[0], de_sample, replace=False)
        a, b = a[idx], b[idx]
    de = delta_e00(a.astype(np.float64), b)
    res = {"gain_angular_deg": float(ang.max()), "gain_angular_p99_deg": float(np.percentile(ang, 99)),
           "raw_max_rel": float(rel.max()), "raw_p99_rel": float(np.percentile(rel, 99)),
           "srgb_de00_p99": float(np.percentile(de, 99)), "srgb_de00_max": float(de.max())}
    if out["srgb"].shape[0] >= 12 and out["srgb"].shape[1] >= 16:
        res["srgb_grid_de00"] = grid_delta_e00(ref["srgb"], out["srgb"].astype(np.float64))[0]
    if not all(np.isfinite(v) for v in res.values()):
        raise RuntimeError(f"non-finite error metric {res}")
    return res


def worst(rows: list[dict[str, float]]) -> dict[str, float]:
    """Element-wise maximum of error dicts (the worst case over scenarios and cubes)."""
    return {k: max(r[k] for r in rows) for k in rows[0]}


def quantisation_de00(ref: dict[str, np.ndarray], bits: int = 8, de_sample: int = 1 << 17) -> float:
    """p99 CIEDE2000 that rounding the reference's sRGB to ``bits`` introduces (context for the
    ΔE00 tolerance: an error below this is invisible in an 8-bit image)."""
    q = np.round(ref["srgb"] * (2 ** bits - 1)) / (2 ** bits - 1)
    return errors({"gain": ref["gain"], "raw": ref["raw"], "srgb": q}, ref, de_sample)["srgb_de00_p99"]

