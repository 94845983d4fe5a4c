"""``GET /sample`` and ``POST /batch``: composed samples, admitted by their memory price."""

from __future__ import annotations

import json
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Query
from fastapi.responses import Response

from service import budget
from service.deps import CtxDep
from service.encoding import MEDIA, encode_image, encode_npz, image_output, meta_json, png_scale
from service.errors import error_responses, fail
from service.models import BatchRequest
from service.sampling import build, plan, price
from service.spec import SampleSpec

router = APIRouter(tags=["samples"])


class _HeldResponse(Response):
    """A response that gives its working-memory reservation back once it is sent — or once sending
    failed (a client that hangs up must not leak the reservation, as a background task would)."""

    def __init__(self, content, hold, **kw) -> None:
        super().__init__(content, **kw)
        self._hold = hold

    async def __call__(self, scope, receive, send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            self._hold.release()

_NPZ = {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}
_SAMPLE_CONTENT = {**_NPZ, "image/png": {"schema": {"type": "string", "format": "binary"}},
                   "image/tiff": {"schema": {"type": "string", "format": "binary"}}}


@router.get("/sample", response_class=Response,
            responses={200: {"content": _SAMPLE_CONTENT,
                             "description": "npz with one array per output (+ meta JSON), or one PNG/TIFF image"},
                       **error_responses(404, 413, 422, 500, 503)})
def sample(params: Annotated[SampleSpec, Query()], ctx: CtxDep) -> Response:
    """One sample: the view lit by the given illuminants, projected through the sensor, with exact
    pixel-wise ground truth. Unknown parameters are refused with the close match."""
    p = plan(params, ctx)
    hold = ctx.memory.acquire(price(p, ctx), f"this sample ({_describe(params, p)})")
    try:
        arrays, meta = build(p, ctx)
        if params.format == "npz":
            body = encode_npz(arrays, meta if "meta" in params.outputs else None)
            headers = {}
        else:
            name = image_output(arrays, params.format)
            noise = params.noise_model() if name == "raw" else None
            meta["encoding"] = png_scale(name, noise) if params.format == "png" else None
            body, headers = encode_image(arrays, params.format, noise=noise, meta=meta)
            headers["X-Illumix-Meta"] = meta_json({k: meta[k] for k in ("scene", "view", "seed", "size",
                                                                         "exposure_gain")})
        del arrays
        return _HeldResponse(body, hold, media_type=MEDIA[params.format], headers=headers)
    except BaseException:
        hold.release()
        raise


@router.post("/batch", response_class=Response,
             responses={200: {"content": _NPZ, "description": "npz with keys '{i}/{output}' and '{i}/meta'"},
                        **error_responses(400, 404, 408, 413, 422, 500, 503)})
def batch(body: BatchRequest, ctx: CtxDep) -> Response:
    """Many samples in one npz (keys ``"{i}/{output}"`` and ``"{i}/meta"``); each item takes the
    ``GET /sample`` parameters (``format`` must stay npz). Priced as a whole before any work."""
    limits = ctx.limits
    if not 1 <= len(body.samples) <= limits.max_batch:
        raise fail(413 if body.samples else 422, f"a batch holds 1..{limits.max_batch} samples, got "
                   f"{len(body.samples)}; split it", code="too_large" if body.samples else "invalid_parameter")
    if any(s.format != "npz" for s in body.samples):
        raise fail(422, "batch items are always npz; drop format= from the items")
    plans = [plan(s, ctx) for s in body.samples]
    # Items are built one after another and their outputs kept for the archive: price the outputs
    # of all (twice: arrays and archive) plus the largest item's working memory.
    outs = sum(budget.output_bytes(p.spec.array_outputs(), len(p.groups), p.out_size[0] * p.out_size[1],
                                   p.metas[0].n_bands) for p in plans)
    work = max(price(p, ctx, encoded=False) for p in plans)
    hold = ctx.memory.acquire(2 * outs + work, f"this batch of {len(plans)} samples")
    try:
        arrays: dict[str, np.ndarray] = {}
        for i, p in enumerate(plans):
            a, meta = build(p, ctx)
            arrays.update({f"{i}/{k}": v for k, v in a.items()})
            if "meta" in p.spec.outputs:
                arrays[f"{i}/meta"] = np.array(json.dumps(meta, allow_nan=False))
        payload = encode_npz(arrays, None)
        del arrays
        return _HeldResponse(payload, hold, media_type=MEDIA["npz"])
    except BaseException:
        hold.release()
        raise


def _describe(spec: SampleSpec, p) -> str:
    w, h = p.out_size
    return f"outputs {','.join(spec.array_outputs()) or 'meta'} at {w}x{h}"
