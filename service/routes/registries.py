"""``/sensors`` and ``/illuminants``: built-in and uploaded spectral data, uploads and deletes.

Uploads are validated completely before anything is written, written atomically, and bounded by
``Limits.max_upload_bytes`` (the store registry's own limit). Writes need the token when the service
has one.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, UploadFile
from starlette.convertors import StringConvertor, register_url_convertor

from illumix.engine import catalogue
from illumix.engine.library import check_upload_name, parse_illuminant, parse_sensor
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.errors import SpectralError, unknown_name
from illumix.retarget.grid import DEFAULT_GRID
from illumix.service.deps import CtxDep, TokenDep
from illumix.service.errors import error_responses, fail
from illumix.service.models import (
    Deleted,
    IlluminantFile,
    IlluminantList,
    IlluminantName,
    SensorDetail,
    SensorFile,
    SensorList,
    SensorName,
    Uploaded,
)
from illumix.store import StoreError

router = APIRouter()


class _SensorName(StringConvertor):
    """A sensor name in a path: anything but ``estimate`` (``POST /sensors/estimate`` has that path)."""

    regex = r"(?!estimate$)[^/]+"


register_url_convertor("sensor_name", _SensorName())
_WRITE_ERRORS = error_responses(400, 401, 408, 409, 413, 422, 503, 507)
_DELETE_ERRORS = error_responses(400, 401, 403, 404, 422, 503, 507)  # 507: a read-only or failing disk


# -- sensors ----------------------------------------------------------------------------------------
@router.get("/sensors", response_model=SensorList, tags=["sensors"])
def sensors(ctx: CtxDep) -> SensorList:
    """Built-in sensors usable on the default grid, the unusable ones with the reason, and uploads."""
    return SensorList.model_validate(catalogue.sensors(ctx))


@router.get("/sensors/{name:sensor_name}", response_model=SensorDetail, tags=["sensors"], responses=error_responses(404, 422))
def sensor_detail(name: str, ctx: CtxDep) -> SensorDetail:
    """One sensor's band-averaged sensitivities on the default grid."""
    s, _ = ctx.library.sensor(name, DEFAULT_GRID)
    return SensorDetail(name=s.name, source=s.source, grid=s.grid.to_dict(),
                        wavelengths=s.grid.wavelengths.tolist(), sensitivities=s.sensitivities.round(8).tolist())


@router.post("/sensors", status_code=201, response_model=Uploaded, tags=["sensors"], dependencies=[TokenDep],
             responses=_WRITE_ERRORS)
async def upload_sensor(name: SensorName, file: SensorFile,
                        ctx: CtxDep, overwrite: Annotated[bool, Form()] = False) -> Uploaded:
    """Register a sensor: a rawtoaces camera JSON or a CSV ``wavelength,r,g,b``."""
    data = await _read(file, ctx.limits.max_upload_bytes)
    check_upload_name("sensors", name, sen.builtin_names())
    _not_reserved(name)
    fmt = "json" if (file.filename or "").lower().endswith(".json") or data.lstrip()[:1] == b"{" else "csv"
    parse_sensor(name, data, fmt, DEFAULT_GRID)  # validate before anything is written
    _put(ctx, "sensors", name, data, fmt, overwrite)
    return Uploaded(name=name, format=fmt, bytes=len(data))


@router.delete("/sensors/{name:sensor_name}", response_model=Deleted, tags=["sensors"], dependencies=[TokenDep],
               responses=_DELETE_ERRORS)
def delete_sensor(name: str, ctx: CtxDep) -> Deleted:
    """Delete an uploaded sensor (built-ins are 403)."""
    if ctx.library.is_builtin_sensor(name):
        raise fail(403, f"sensor {name!r} is built in; only uploaded sensors can be deleted")
    return _delete(ctx, "sensors", name)


# -- illuminants ------------------------------------------------------------------------------------
@router.get("/illuminants", response_model=IlluminantList, tags=["illuminants"])
def illuminants(ctx: CtxDep) -> IlluminantList:
    """Built-in, parametric (``blackbody:K``, ``daylight:K``) and uploaded illuminants."""
    return IlluminantList.model_validate(catalogue.illuminants(ctx))


@router.post("/illuminants", status_code=201, response_model=Uploaded, tags=["illuminants"],
             dependencies=[TokenDep], responses=_WRITE_ERRORS)
async def upload_illuminant(name: IlluminantName, file: IlluminantFile,
                            ctx: CtxDep, overwrite: Annotated[bool, Form()] = False) -> Uploaded:
    """Register an illuminant: a CSV ``wavelength,value`` (any positive scale; normalised photometrically)."""
    data = await _read(file, ctx.limits.max_upload_bytes)
    check_upload_name("illuminants", name, ill.builtin_names())
    parse_illuminant(name, data, DEFAULT_GRID)
    _put(ctx, "illuminants", name, data, "csv", overwrite)
    return Uploaded(name=name, format="csv", bytes=len(data))


@router.delete("/illuminants/{name}", response_model=Deleted, tags=["illuminants"], dependencies=[TokenDep],
               responses=_DELETE_ERRORS)
def delete_illuminant(name: str, ctx: CtxDep) -> Deleted:
    """Delete an uploaded illuminant (built-ins are 403)."""
    if name in ill.builtin_names() or name.partition(":")[0].lower() in ill.PARAMETRIC:
        raise fail(403, f"illuminant {name!r} is built in; only uploaded illuminants can be deleted")
    return _delete(ctx, "illuminants", name)


# -- helpers ----------------------------------------------------------------------------------------
def _not_reserved(name: str) -> None:
    if name.lower() == "estimate":
        raise SpectralError("'estimate' names the estimation endpoint (POST /sensors/estimate); choose another name")



async def _read(file: UploadFile, limit: int) -> bytes:
    data = await file.read(limit + 1)
    if len(data) > limit:
        raise fail(413, f"the upload exceeds the {limit}-byte limit; upload a smaller file", code="too_large")
    if not data:
        raise SpectralError("the uploaded file is empty")
    return data


def _put(ctx, kind: str, name: str, data: bytes, fmt: str, overwrite: bool) -> None:
    registry = ctx.store.registry(kind, max_bytes=ctx.limits.max_upload_bytes)
    if name in registry.names() and not overwrite:
        raise fail(409, f"{name!r} exists; send overwrite=true to replace it")
    try:
        registry.put(name, data, fmt, overwrite=overwrite)
    except StoreError as exc:
        if getattr(exc, "errno", None) is not None:
            raise  # the disk, not the input: 507/503 by the store handler
        raise SpectralError(str(exc)) from None


def _delete(ctx, kind: str, name: str) -> Deleted:
    """Delete an upload; it needs no new space (:meth:`store.registry.Registry.delete`), so a full disk
    can be freed through the API."""
    registry = ctx.store.registry(kind)
    if name not in registry.names():
        raise unknown_name(f"uploaded {kind[:-1]}", name, registry.names())
    registry.delete(name)
    return Deleted(deleted=name)
