"""The ground-truth composition of :mod:`retarget.compose` in torch, for a GPU (``device="cuda"``).

The same equations, term for term (DESIGN.md "The key idea", "Ground truth"), for the outputs a
training feed asks for — ``raw``, ``gain``, ``mask``, ``weights``, ``illum``, ``mixture`` — on
windows of cubes already on the device:

    R_g      = a_g · T_g @ M_g                      M_g = diag(Φ̄_g/Ē_g) C Δλ   (B, 3), intensity 1
    raw      = Σ_g R_g
    formula  ω_g = R_{g,G} / Σ_h R_{h,G};  W = Σ_g ω_g w_g                     (thesis eq. 3.3)
    physical U = Σ_g a_g · U_g @ M_g;  mixture_g = U_{g,G}/U_G;  W = U/U_G
    gain_k   = max_j W_j / W_k

Pixels with no light (``Σ R_G`` ≤ ``rel_eps`` × the frame's peak) get the frame's light-weighted
mean weights and ``mask`` False, as in :func:`retarget.groundtruth.illuminant_weights`. float32
throughout; ``tests/test_compose_torch.py`` checks it against the numpy path. torch is imported
only by this module.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence

import numpy as np
import torch

from illumix.retarget.errors import SpectralError
from illumix.retarget.groundtruth import DEFAULT_REL_EPS, MIN_CHANNEL_RATIO

TORCH_OUTPUTS = frozenset({"raw", "gain", "mask", "weights", "illum", "mixture"})
_PRECISION_LOCK = threading.Lock()  # torch.set_float32_matmul_precision is process-wide


def _weights(green: torch.Tensor, prior: torch.Tensor, rel_eps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``(weights (H, W, G), mask (H, W))`` from per-group green ``(G, H, W)`` (eq. 3.3)."""
    g = green.clamp_min(0)
    total = g.sum(0)
    peak = total.max() if total.numel() else total.new_zeros(())
    mask = total > torch.clamp(rel_eps * peak, min=torch.finfo(torch.float32).tiny)
    lit = mask.sum()
    frame = (g * mask).sum((1, 2), dtype=torch.float64)
    fallback = torch.where(lit > 0, frame / frame.sum().clamp_min(1e-300),
                           prior.double() / prior.double().sum().clamp_min(1e-300)).float()
    w = torch.where(mask, g / torch.where(mask, total, torch.ones_like(total)), fallback[:, None, None])
    return w.permute(1, 2, 0), mask


def _gain(white: torch.Tensor) -> torch.Tensor:
    if not bool((white > 0).all()):
        raise SpectralError("gain map: a white point has a zero, negative or NaN channel")
    gain = white.amax(-1, keepdim=True) / white
    if not bool(torch.isfinite(gain).all()):
        raise SpectralError("gain map: a gain exceeds float32; one white-point channel is (nearly) zero")
    return gain


def _project(windows: Sequence[torch.Tensor | None], unit_weights: Sequence[np.ndarray | None], a: torch.Tensor,
             shape: tuple[int, int], dev: torch.device) -> torch.Tensor:
    """Per-group camera RGB ``R_g = a_g · T_g @ M_g`` ``(G, H, W, 3)`` float32 of the windows (zeros for
    a group not read, not weighted or at intensity 0); :class:`SpectralError` for NaN or inf."""
    h, w = shape
    out = torch.zeros((len(windows), h, w, 3), dtype=torch.float32, device=dev)
    # full float32 products whatever the caller's torch.set_float32_matmul_precision (TF32 would
    # cost ~1e-3 relative); restored after. The setting is process-wide and the service composes
    # in several threads: one lock around set, products and restore, or a thread could restore
    # another's setting mid-product (the products share one device anyway)
    with _PRECISION_LOCK:
        precision = torch.get_float32_matmul_precision()
        torch.set_float32_matmul_precision("highest")
        try:
            for g, (c, m) in enumerate(zip(windows, unit_weights)):
                if c is not None and m is not None and float(a[g]) > 0:
                    mt = torch.as_tensor(np.asarray(m, np.float32), device=dev)
                    out[g] = (c.reshape(-1, c.shape[-1]).float() @ mt).reshape(h, w, 3) * a[g]
        finally:
            torch.set_float32_matmul_precision(precision)
    if not bool(torch.isfinite(out).all()):
        raise SpectralError("project: a cube contains NaN or inf (or overflowed float32)")
    return out


def _physical(u: torch.Tensor, a: torch.Tensor, wps: torch.Tensor,
              rel_eps: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The physical ground truth ``(mixture (H, W, G), white (H, W, 3), mask (H, W))`` from the
    groups' illumination cubes in camera RGB ``u`` ``(G, H, W, 3)``: ``W = U/U_G`` where every
    channel of ``U`` is lit, else the mixture's white point; each channel floored at
    ``MIN_CHANNEL_RATIO`` of the largest."""
    mixture, mask = _weights(u[..., 1], a, rel_eps)
    total = u.sum(0)
    ok = mask & (total > 0).all(-1)
    white = torch.where(ok[..., None], total / torch.where(ok, total[..., 1], torch.ones_like(total[..., 1]))[..., None],
                        mixture @ wps)
    white = torch.maximum(white, MIN_CHANNEL_RATIO * white.amax(-1, keepdim=True))
    return mixture, white, ok


def compose_torch(cubes: Sequence[torch.Tensor | None], unit_weights: Sequence[np.ndarray | None],
                  intensities: Sequence[float], white_points: np.ndarray, *, outputs: Iterable[str],
                  illumination: Sequence[torch.Tensor | None] | None = None, valid: torch.Tensor | None = None,
                  rel_eps: float = DEFAULT_REL_EPS, shape: tuple[int, int] | None = None,
                  device: str | torch.device | None = None) -> dict[str, torch.Tensor]:
    """Outputs ``(H, W, C)`` float32 tensors (``mask`` ``(H, W)`` bool) on the cubes' device.

    cubes : per group a window ``(H, W, B)`` on the device, or ``None`` for a group not lit;
    unit_weights : per group ``M_g`` ``(B, 3)`` at intensity 1 (:func:`retarget.relight.raw_weights`);
    intensities : ``a_g``; white_points : ``(G, 3)`` sensor white points (G = 1);
    illumination : per group the illumination cube window (physical ground truth) or ``None``;
    valid : optional ``(H, W)`` bool of pixels where the ground truth is defined.
    """
    want = set(outputs)
    if want - TORCH_OUTPUTS:
        raise SpectralError(f"the torch composition serves {', '.join(sorted(TORCH_OUTPUTS))}; "
                            f"not {', '.join(sorted(want - TORCH_OUTPUTS))}")
    ref = next((c for c in cubes if c is not None), None)
    if ref is None and (shape is None or device is None):
        raise SpectralError("compose_torch: no cube is read; give shape= and device= for an all-dark frame")
    dev, (h, w) = (ref.device, ref.shape[:2]) if ref is not None else (torch.device(device), shape)
    a = torch.tensor([float(x) for x in intensities], dtype=torch.float32, device=dev)

    group_raw = _project(cubes, unit_weights, a, (h, w), dev)
    res: dict[str, torch.Tensor] = {}
    if "raw" in want:
        res["raw"] = group_raw.sum(0)
    if not (want - {"raw"}):
        return res
    wps = torch.as_tensor(np.asarray(white_points, np.float32), device=dev)
    weights, mask = _weights(group_raw[..., 1], a, rel_eps)
    if "weights" in want:
        res["weights"] = weights
    if illumination is None:
        mixture, white = weights, weights @ wps
    else:
        mixture, white, mask = _physical(_project(illumination, unit_weights, a, (h, w), dev), a, wps, rel_eps)
    if valid is not None:
        mask = mask & valid
    if "mask" in want:
        res["mask"] = mask
    if "mixture" in want:
        res["mixture"] = mixture
    if "illum" in want:
        res["illum"] = white
    if "gain" in want:
        res["gain"] = _gain(white)
    return res
