"""Composition on a torch device (``illumix serve --device cuda``, the client's local ``device=``).

Decoded cubes are copied once to the device and kept there (an LRU bounded by ``device_cache_mb``);
each eligible request composes its window there with :func:`retarget.compose_torch.compose_torch`
— the same equations as :func:`retarget.compose.compose`, in float32 — and the arrays come back to
the host for encoding (the service) or stay on the device (the local mode's training feed).

Eligible: outputs among ``raw``, ``gain``, ``mask``, ``weights``, ``illum``, ``mixture`` (and
``meta``), at the cropped size, without ``noise=``, ``bayer=`` or ``exposure=``. The service composes
anything else on the CPU as before; the local mode refuses it with the reason.
torch is imported only here, and only when a device is asked for.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from illumix.engine import cubes
from illumix.engine.sample_meta import sample_meta
from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite
from illumix.retarget.groundtruth import lit_white_points
from illumix.store.lru import LRUCache


def refusal(spec) -> str | None:
    """Why ``spec`` cannot be composed on a device (``None``: it can)."""
    from illumix.retarget.compose_torch import TORCH_OUTPUTS

    outputs = set(spec.array_outputs())
    bad = sorted(outputs - TORCH_OUTPUTS) + [f"{k}=" for k in ("size", "noise", "bayer", "exposure")
                                             if getattr(spec, k) is not None]
    if spec.format not in ("npz", "arrays"):
        bad.append(f"format={spec.format}")  # images and files: auto-exposed raw (sampling.exposure_for), levels
    if not outputs or bad:
        return (f"the device composes {', '.join(sorted(TORCH_OUTPUTS))} at the cropped size; "
                f"{', '.join(bad) or 'no array output'} need the CPU path")
    return None


class TorchComposer:
    """Cubes on ``device`` and the composition of a planned sample there."""

    def __init__(self, device: str, device_cache_mb: int = 8192) -> None:
        import torch

        self.torch = torch
        self.device = torch.device(device)
        if self.device.type == "cuda" and not torch.cuda.is_available():
            raise RuntimeError("torch sees no CUDA device (torch.cuda.is_available() is False)")
        try:  # a device torch names but cannot compute on (meta, a cuda index out of range): refuse at start
            torch.zeros(1, device=self.device).cpu()
        except Exception as exc:
            raise RuntimeError(f"torch cannot compute on it ({str(exc).splitlines()[0]})") from None
        self.cubes = LRUCache(device_cache_mb * 2**20, cost=lambda t: t.numel() * t.element_size())

    def out_of_memory(self, exc: BaseException) -> bool:
        """Whether ``exc`` is the device running out of memory (the service then uses the CPU)."""
        oom = getattr(self.torch, "OutOfMemoryError", None) or getattr(self.torch.cuda, "OutOfMemoryError", None)
        return oom is not None and isinstance(exc, oom)

    def _to_device(self, a: np.ndarray, copy: bool = False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # read-only cached arrays: nothing writes to them
            t = self.torch.from_numpy(np.asarray(a)).to(self.device)
        return t.clone() if copy else t

    def _window(self, ctx, p, group: str, kind: str):
        x, y, w, h = p.window

        nbytes = cubes.cube_bytes(p)
        if nbytes > ctx.cache.max_cost or nbytes > self.cubes.max_cost:
            return self._to_device(cubes.read_cube(ctx, p, group, kind))  # the window, uncached

        def load():
            # a copy on "cpu" too: the device cache then owns its memory, within device_cache_mb
            return self._to_device(cubes.whole_cube(ctx, p, group, kind), copy=self.device.type == "cpu")

        full = self.cubes.get(cubes.plan_cube_key(p, group, kind), load, expected_cost=nbytes)
        return full[y:y + h, x:x + w]

    def compose(self, ctx, p, unit: list, white_points: np.ndarray, valid: np.ndarray | None) -> dict:
        """``{output: tensor on the device}`` of plan ``p``; ``unit``: per group the band weights at
        intensity 1 (``None`` for a group not read); ``white_points`` ``(G, 3)``."""
        from illumix.retarget.compose_torch import compose_torch

        lit = p.reads()
        cubes = [self._window(ctx, p, g, "transport") if r else None for g, r in zip(p.groups, lit)]
        outputs = set(p.spec.array_outputs())
        physical = p.gt == "physical" and bool(outputs - {"raw", "weights"})
        illum = [self._window(ctx, p, g, "illumination") if r else None
                 for g, r in zip(p.groups, lit)] if physical else None
        v = None if valid is None else self.torch.from_numpy(np.ascontiguousarray(valid)).to(self.device)
        return compose_torch(cubes, unit, p.intensities, white_points, outputs=outputs, illumination=illum, valid=v,
                             shape=(p.window[3], p.window[2]), device=self.device)


def build_on_device(p, ctx, unit, sensor, spds, ccms, fit_de, valid, reasons, keep_device: bool,
                     t0: float, t_setup: float) -> tuple[dict, dict]:
    """:func:`build` on ``ctx.torch``'s device (an eligible request: :func:`torch_refusal`)."""
    wps = lit_white_points(sensor.weights(), np.stack(spds), p.intensities)  # as retarget.compose
    out = ctx.torch.compose(ctx, p, unit, wps, valid)
    mask = out.get("mask")
    host_mask = None if mask is None else mask.cpu().numpy()
    arrays = out if keep_device else {k: v.cpu().numpy() for k, v in out.items()}
    floats = {k: a for k, a in arrays.items() if a.dtype != (ctx.torch.torch.bool if keep_device else np.bool_)}
    if keep_device:  # one reduction per output, one device sync for all
        t = ctx.torch.torch
        finite = t.stack([t.isfinite(a).all() for a in floats.values()]).cpu().numpy() if floats else []
    else:
        finite = [all_finite(a) for a in floats.values()]
    for k, ok in zip(floats, finite):
        if not ok:
            raise SpectralError(f"the composed {k} overflows float32 (intensities × the stored radiance is too "
                                "large); lower intensities=")
    t_compose = time.perf_counter()
    meta = sample_meta(p, sensor, wps, ccms, fit_de, host_mask, valid, reasons, 1.0, None,
                 {"setup": 1e3 * (t_setup - t0), "compose": 1e3 * (t_compose - t_setup)})
    meta["device"] = str(ctx.torch.device)
    return arrays, meta
