"""``GET /sample`` and ``POST /batch``: composed samples, admitted by their memory price."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from fastapi.responses import Response

from illumix.engine import budget
from illumix.engine.sampling import build, plan, price
from illumix.engine.spec import SampleSpec
from illumix.service import arrays_format
from illumix.service.deps import CtxDep
from illumix.service.encoders import ENCODERS, encoder, wire_arrays
from illumix.service.encoding import MEDIA
from illumix.service.errors import error_responses, fail
from illumix.service.models import BatchRequest

router = APIRouter(tags=["samples"])
#: an arrays body is sent in slices of at most this many bytes (views, not copies): the server's
#: HTTP layer copies what it is given into its write buffer, so small slices keep that copy small
#: and let the send overlap it (bench/wire.py measures it)
SEND_CHUNK = 1 << 18


class HeldResponse(Response):
    """A response that gives its working-memory reservation back once it is sent — or once sending
    failed (a client that hangs up must not leak the reservation, as a background task would).

    ``content`` is bytes, or an :class:`service.arrays_format.Encoded` whose chunks (views of the
    outputs themselves) are sent one after another, so the arrays are never copied into one body."""

    def __init__(self, content, hold, **kw) -> None:
        self._chunks = None
        if isinstance(content, arrays_format.Encoded):
            self._chunks, content = content, b""
        super().__init__(content, **kw)
        if self._chunks is not None:
            self.headers["content-length"] = str(self._chunks.nbytes)
        self._hold = hold

    async def __call__(self, scope, receive, send) -> None:
        try:
            if self._chunks is None:
                await super().__call__(scope, receive, send)
                return
            await send({"type": "http.response.start", "status": self.status_code, "headers": self.raw_headers})
            step = SEND_CHUNK
            parts = [c[i:i + step] for c in self._chunks.chunks for i in range(0, len(c), step)]
            for i, part in enumerate(parts):
                await send({"type": "http.response.body", "body": part, "more_body": i < len(parts) - 1})
        finally:
            self._chunks = None
            self._hold.release()


_BINARY = {"schema": {"type": "string", "format": "binary"}}
_NPZ = {"application/octet-stream": _BINARY, arrays_format.MEDIA_TYPE: _BINARY}
_SAMPLE_CONTENT = {**_NPZ, **{MEDIA[f]: _BINARY for f in ("png", "tiff", "dng", "exr")}}


@router.get("/sample", response_class=Response,
            responses={200: {"content": _SAMPLE_CONTENT,
                             "description": "npz or arrays container with one array per output (+ meta JSON), "
                                            "one PNG/TIFF image, a DNG of the raw or an OpenEXR of the outputs"},
                       **error_responses(404, 413, 422, 500, 501, 503)})
def sample(params: Annotated[SampleSpec, Query()], ctx: CtxDep) -> Response:
    """One sample: the view lit by the given illuminants, projected through the sensor, with exact
    pixel-wise ground truth. Unknown parameters are refused with the close match."""
    enc = encoder(params.format)
    p = plan(enc.compose_spec(params), ctx)
    enc.check(p)
    hold = ctx.memory.acquire(price(p, ctx) + enc.extra_bytes(p), f"this sample ({_describe(params, p)})")
    try:
        arrays, meta = build(p, ctx)
        body, headers = enc.encode(p, ctx, arrays, meta)
        del arrays
        return HeldResponse(body, hold, media_type=enc.media_type, headers=headers)
    except BaseException:
        hold.release()
        raise


@router.post("/batch", response_class=Response,
             responses={200: {"content": _NPZ, "description": "npz with keys '{i}/{output}' and '{i}/meta' (and "
                                                              "'{i}/scales' with dtype=float16), or an arrays "
                                                              "container with arrays '{i}/{output}' and the metas "
                                                              "in the header's items"},
                        **error_responses(400, 404, 408, 413, 422, 500, 503)})
def batch(body: BatchRequest, ctx: CtxDep) -> Response:
    """Many samples in one answer; each item takes the ``GET /sample`` parameters. ``format`` is npz
    (keys ``"{i}/{output}"``, ``"{i}/meta"``, ``"{i}/scales"``) or arrays (arrays ``"{i}/{output}"``,
    header ``items[i].meta``, scales on the arrays), the same for every item; ``dtype`` may differ
    per item. Priced as a whole before any work."""
    limits = ctx.limits
    if not 1 <= len(body.samples) <= limits.max_batch:
        raise fail(413 if body.samples else 422, f"a batch holds 1..{limits.max_batch} samples, got "
                   f"{len(body.samples)}; split it", code="too_large" if body.samples else "invalid_parameter")
    enc = encoder(body.samples[0].format)
    if not enc.batch or any(s.format != enc.name for s in body.samples):
        batchable = " or ".join(n for n, e in ENCODERS.items() if e.batch)
        raise fail(422, f"batch items are all {batchable}; give every item the same format= (or none: npz)")
    plans = [plan(s, ctx) for s in body.samples]
    # Items are built one after another and their outputs kept for the archive: price the outputs
    # of all (twice: arrays and archive) plus the largest item's working memory.
    outs = sum(budget.output_bytes(p.spec.array_outputs(), len(p.groups), p.out_size[0] * p.out_size[1],
                                   p.metas[0].n_bands) for p in plans)
    work = max(price(p, ctx, encoded=False) for p in plans)
    hold = ctx.memory.acquire(2 * outs + work, f"this batch of {len(plans)} samples")
    try:
        items = []
        for p in plans:
            a, meta = build(p, ctx)
            a, scales = wire_arrays(p.spec, a, meta)
            items.append((a, scales, meta if "meta" in p.spec.outputs else None))
        payload = enc.encode_batch(items)
        del items
        return HeldResponse(payload, hold, media_type=enc.media_type)
    except BaseException:
        hold.release()
        raise


def _describe(spec: SampleSpec, p) -> str:
    w, h = p.out_size
    return f"outputs {','.join(spec.array_outputs()) or 'meta'} at {w}x{h}"
