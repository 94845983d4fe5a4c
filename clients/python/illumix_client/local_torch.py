"""The local mode's torch composition (``LocalClient(store, device="cuda")``).

Cubes are decoded once (the local client's cube cache) and kept on the device; each sample is a
window of them projected and turned into ground truth by :func:`retarget.compose_torch.compose_torch`
— a few tensor products per group, so a GPU composes far more crops per second than the CPU
path. It serves ``raw``, ``gain``, ``mask``, ``weights``, ``illum``, ``mixture`` (and ``meta``) at
the cropped size, without ``size=``, ``noise=``, ``bayer=`` or ``exposure=``: those need the CPU
path (``device=None``). Sample arrays are torch tensors on the device, ``(H, W, C)`` like the
numpy ones.
"""

from __future__ import annotations

import warnings

import numpy as np
import torch

from illumix_client.errors import InvalidRequestError
from illumix_client.sample import Sample
from retarget.compose_torch import TORCH_OUTPUTS, compose_torch
from retarget.groundtruth import white_points
from retarget.relight import band_scales, raw_weights
from service import extra_outputs as extra
from service.sampling import _aov_reader, _key, plan, whole_cube
from store.lru import LRUCache


class TorchComposer:
    """Composes :class:`service.spec.SampleSpec` requests on ``device`` from ``ctx``'s store."""

    def __init__(self, ctx, device: str, cache_mb: int) -> None:
        self.ctx, self.device = ctx, torch.device(device)
        self.cubes: LRUCache[torch.Tensor] = LRUCache(cache_mb * 2**20, cost=lambda t: t.numel() * t.element_size())

    def _to_device(self, cube: np.ndarray) -> torch.Tensor:
        with warnings.catch_warnings():
            # the cached cube is read-only; nothing here writes to it (on "cpu" the tensor shares it)
            warnings.simplefilter("ignore", UserWarning)
            return torch.from_numpy(cube).to(self.device)

    def _window(self, p, group: str, kind: str) -> torch.Tensor:
        x, y, w, h = p.window
        full = self.cubes.get(_key(p, group, kind), lambda: self._to_device(whole_cube(self.ctx, p, group, kind)),
                              expected_cost=p.full[0] * p.full[1] * p.metas[0].n_bands * 4)
        return full[y:y + h, x:x + w]

    def sample(self, spec) -> Sample:
        outputs = set(spec.array_outputs())
        unsupported = [k for k in ("size", "noise", "bayer", "exposure") if getattr(spec, k) is not None]
        if outputs - TORCH_OUTPUTS or unsupported:
            what = sorted(outputs - TORCH_OUTPUTS) + [f"{k}=" for k in unsupported]
            raise InvalidRequestError(f"device={self.device.type} composes {', '.join(sorted(TORCH_OUTPUTS))} at the "
                                      f"cropped size; {', '.join(what)} need the CPU path (device=None)", 422)
        ctx = self.ctx
        p = plan(spec, ctx)
        grid = p.metas[0].spectral_grid
        sensor, _ = ctx.library.sensor(spec.sensor, grid)
        spds = np.stack([ctx.library.illuminant(n or "E", grid)[0] for n in p.names])
        lit = p.reads()
        emissions = [np.asarray(m.emission, np.float64) for m in p.metas]
        unit = [raw_weights(band_scales(s[None], e[None], np.ones(1), [g], grid.wavelengths), sensor.weights())[0]
                if r else None for s, e, g, r in zip(spds, emissions, p.groups, lit)]
        wps = np.ones((len(p.groups), 3))
        if any(lit):
            wps[lit] = white_points(sensor.weights(), spds[lit])
        cubes = [self._window(p, g, "transport") if r else None for g, r in zip(p.groups, lit)]
        physical = p.gt == "physical" and bool(outputs - {"raw", "weights"})
        illum = [self._window(p, g, "illumination") if r else None for g, r in zip(p.groups, lit)] if physical else None
        valid, _ = extra.view_validity(_aov_reader(ctx, p), *p.out_size)
        out = compose_torch(cubes, unit, p.intensities, wps, outputs=outputs, illumination=illum,
                            valid=None if valid is None else torch.from_numpy(np.ascontiguousarray(valid)).to(self.device))
        meta = {"scene": p.scene, "view": p.view, "groups": p.groups, "seed": p.seed, "crop": list(p.window),
                "sensor": {"name": sensor.name, "source": sensor.source}, "device": str(self.device),
                "illuminants": [{"group": g, "illuminant": n, "intensity": a, "white_point_rgb": [float(v) for v in wp]}
                                for g, n, a, wp in zip(p.groups, p.names, p.intensities, wps)],
                "ground_truth": {"method": "physical" if physical else "formula"}}
        s = Sample(meta=meta if "meta" in spec.outputs else {})
        for k, v in out.items():
            setattr(s, k, v)
        return s
