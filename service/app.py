"""The FastAPI app (DESIGN.md "Service"). Build it with :func:`create_app`; run it with ``illumix serve``.

Reads are open; writes (uploading or deleting sensors and illuminants) need
``Authorization: Bearer TOKEN`` when the app has a token. Bad input is a 4xx with a message a person
can act on — never a 500 — and no response carries NaN or inf (pixels with no light are flagged in
``mask``).
"""

from __future__ import annotations

import json
import secrets
from typing import Annotated

import numpy as np
from fastapi import Depends, FastAPI, File, Form, Header, HTTPException, Query, Request, UploadFile
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ValidationError

from retarget import illuminants as ill
from retarget import sensors as sen
from retarget.errors import SpectralError, UnknownName
from retarget.grid import DEFAULT_GRID
from service.cache import ArrayCache
from service.encoding import MEDIA, encode_image, encode_npz
from service.library import Library, check_upload_name, parse_illuminant, parse_sensor
from service.limits import Limits
from service.sampling import Context, NotFound, build_sample
from service.spec import SampleSpec
from store import StoreError, StoreKeyError


class BatchRequest(BaseModel):
    samples: list[dict]


def _spec(params: dict) -> SampleSpec:
    try:
        return SampleSpec(**{k: v for k, v in params.items() if v is not None})
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        if first["type"] == "extra_forbidden":
            raise SpectralError(f"unknown parameter {where!r}; see /docs for the sample parameters") from None
        raise SpectralError(f"{where}: {first['msg'].removeprefix('Value error, ')}") from None


def create_app(store, *, token: str | None = None, cache_mb: int = 1024, limits: Limits | None = None) -> FastAPI:
    """The service over an open :class:`store.CubeStore`."""
    limits = limits or Limits()
    token = token or None  # an empty token would accept an empty Bearer header: treat as none
    ctx = Context(store=store, library=Library(store), cache=ArrayCache(cache_mb * 2**20), limits=limits)
    app = FastAPI(title="illumix", version="0.1.0",
                  description="Mixed-illuminant colour-constancy samples with exact ground truth.")
    app.state.ctx = ctx

    def require_token(authorization: Annotated[str | None, Header()] = None) -> None:
        if token is None:
            return
        given = (authorization or "").removeprefix("Bearer ").strip()
        if not authorization or not secrets.compare_digest(given, token):
            raise HTTPException(401, "this write needs 'Authorization: Bearer <token>' with the "
                                     "service's token", headers={"WWW-Authenticate": "Bearer"})

    @app.exception_handler(UnknownName)
    @app.exception_handler(NotFound)
    async def _not_found(request: Request, exc: Exception):
        return JSONResponse({"detail": str(exc)}, status_code=404)

    @app.exception_handler(StoreKeyError)
    async def _store_missing(request: Request, exc: StoreKeyError):
        return JSONResponse({"detail": str(exc)}, status_code=404)

    @app.exception_handler(StoreError)
    async def _store_broken(request: Request, exc: StoreError):
        # Not the client's fault: the store itself is damaged or unreachable.
        return JSONResponse({"detail": f"store problem: {exc}; run `illumix store verify`"}, status_code=503)

    @app.exception_handler(SpectralError)
    async def _bad_input(request: Request, exc: SpectralError):
        return JSONResponse({"detail": str(exc)}, status_code=422)

    @app.get("/health")
    def health() -> dict:
        return {"status": "ok", "scenes": len(store.scenes()), "cache_bytes": ctx.cache.nbytes,
                "cache_hits": ctx.cache.hits, "cache_misses": ctx.cache.misses}

    @app.get("/scenes")
    def scenes() -> dict:
        out = []
        for s in store.scenes():
            views = []
            for v in store.views(s):
                vm = store.view_meta(s, v)
                groups = [{"name": g, "emission": store.cube_meta(s, v, g).emission_name}
                          for g in store.groups(s, v)]
                views.append({"name": v, "width": vm.width, "height": vm.height, "groups": groups})
            out.append({"name": s, "views": views})
        return {"scenes": out}

    @app.get("/sample", responses={200: {"content": {"application/octet-stream": {}, "image/png": {},
                                                         "image/tiff": {}}}})
    def sample(
        scene: str | None = None, view: str | None = None,
        seed: Annotated[int | None, Query(ge=0)] = None,
        sensor: str = Query("XYZ", description="built-in or uploaded sensor name"),
        pair: str | None = Query(None, description="two illuminants for the view's first two groups, e.g. A,D65"),
        illuminants: str | None = Query(None, description="one illuminant per light group"),
        intensities: str | None = Query(None, description="one intensity per lit group, default 1"),
        crop: str | None = Query(None, description="x,y,w,h"),
        size: str | None = Query(None, description="WxH output size (area resampling)"),
        outputs: str | None = Query(None, description="raw,gain,ccm,srgb,weights,mask,meta"),
        format: str = Query("npz", description="npz, png or tiff"),
        exposure: str | None = Query(None, description="auto, adaptive or a number"),
        noise: str | None = Query(None, description="low, phone, high or key:value;…"),
        bayer: str | None = Query(None, description="RGGB, BGGR, GRBG or GBRG"),
    ) -> Response:
        spec = _spec(dict(scene=scene, view=view, seed=seed, sensor=sensor, pair=pair,
                          illuminants=illuminants, intensities=intensities, crop=crop, size=size,
                          outputs=outputs, format=format, exposure=exposure, noise=noise, bayer=bayer))
        return _respond(spec, ctx)

    @app.post("/batch")
    def batch(body: BatchRequest) -> Response:
        """Many sample specs (the /sample parameters as JSON objects) → one npz with keys
        ``"{i}/{output}"`` and ``"{i}/meta"``."""
        if not body.samples or len(body.samples) > limits.max_batch:
            raise SpectralError(f"batch needs 1..{limits.max_batch} samples, got {len(body.samples)}")
        specs = [_spec(s) for s in body.samples]
        if any(s.format != "npz" for s in specs):
            raise SpectralError("batch items are always npz; drop format= from the items")
        arrays: dict = {}
        pixels = 0
        for i, spec in enumerate(specs):
            a, meta = build_sample(spec, ctx)
            pixels += meta["size"][0] * meta["size"][1]
            if pixels > limits.max_batch_pixels:
                raise SpectralError(f"batch output exceeds {limits.max_batch_pixels} pixels; use fewer "
                                    "or smaller samples")
            arrays.update({f"{i}/{k}": v for k, v in a.items()})
            if "meta" in spec.outputs:
                arrays[f"{i}/meta"] = np.array(json.dumps(meta))
        return Response(encode_npz(arrays, None), media_type=MEDIA["npz"])

    # -- sensors ------------------------------------------------------------------------------
    @app.get("/sensors")
    def sensors() -> dict:
        return {"builtin": sen.builtin_names(), "uploaded": ctx.library.uploaded_sensors()}

    @app.get("/sensors/{name}")
    def sensor_detail(name: str) -> dict:
        s, _ = ctx.library.sensor(name, DEFAULT_GRID)
        return {"name": s.name, "source": s.source, "grid": s.grid.to_dict(),
                "wavelengths": s.grid.wavelengths.tolist(), "sensitivities": s.sensitivities.round(8).tolist()}

    @app.post("/sensors", status_code=201, dependencies=[Depends(require_token)])
    async def upload_sensor(name: Annotated[str, Form()], file: Annotated[UploadFile, File()],
                            overwrite: Annotated[bool, Form()] = False) -> dict:
        data = await _read_upload(file, limits)
        check_upload_name("sensors", name, sen.builtin_names())
        fmt = "json" if (file.filename or "").lower().endswith(".json") or data.lstrip()[:1] == b"{" else "csv"
        parse_sensor(name, data, fmt, DEFAULT_GRID)  # validate before anything is written
        _put(store.registry("sensors"), name, data, fmt, overwrite)
        return {"name": name, "format": fmt, "bytes": len(data)}

    @app.delete("/sensors/{name}", dependencies=[Depends(require_token)])
    def delete_sensor(name: str) -> dict:
        if ctx.library.is_builtin_sensor(name):
            raise HTTPException(403, f"sensor {name!r} is built in; only uploaded sensors can be deleted")
        reg = store.registry("sensors")
        if name not in reg.names():
            raise UnknownName(f"no uploaded sensor {name!r}; uploaded: {', '.join(reg.names()) or 'none'}")
        reg.delete(name)
        return {"deleted": name}

    # -- illuminants --------------------------------------------------------------------------
    @app.get("/illuminants")
    def illuminants_list() -> dict:
        return {"builtin": ill.builtin_names(),
                "parametric": {k: {"min_kelvin": lo, "max_kelvin": hi} for k, (lo, hi) in ill.PARAMETRIC.items()},
                "uploaded": ctx.library.uploaded_illuminants()}

    @app.post("/illuminants", status_code=201, dependencies=[Depends(require_token)])
    async def upload_illuminant(name: Annotated[str, Form()], file: Annotated[UploadFile, File()],
                                overwrite: Annotated[bool, Form()] = False) -> dict:
        data = await _read_upload(file, limits)
        check_upload_name("illuminants", name, ill.builtin_names())
        parse_illuminant(name, data, DEFAULT_GRID)
        _put(store.registry("illuminants"), name, data, "csv", overwrite)
        return {"name": name, "format": "csv", "bytes": len(data)}

    return app


async def _read_upload(file: UploadFile, limits: Limits) -> bytes:
    data = await file.read(limits.max_upload_bytes + 1)
    if len(data) > limits.max_upload_bytes:
        raise HTTPException(413, f"upload exceeds {limits.max_upload_bytes} bytes")
    if not data:
        raise SpectralError("the uploaded file is empty")
    return data


def _put(registry, name: str, data: bytes, fmt: str, overwrite: bool) -> None:
    if name in registry.names() and not overwrite:
        raise HTTPException(409, f"{name!r} exists; send overwrite=true to replace it")
    try:
        registry.put(name, data, fmt, overwrite=overwrite)
    except StoreError as exc:
        raise SpectralError(str(exc)) from None


def _respond(spec: SampleSpec, ctx: Context) -> Response:
    arrays, meta = build_sample(spec, ctx)
    if spec.format == "npz":
        body = encode_npz(arrays, meta if "meta" in spec.outputs else None)
        return Response(body, media_type=MEDIA["npz"])
    body, headers = encode_image(arrays, spec.format, noisy_raw=bool(spec.noise))
    headers["X-Illumix-Meta"] = json.dumps({k: meta[k] for k in ("scene", "view", "seed", "size")})
    return Response(body, media_type=MEDIA[spec.format], headers=headers)
