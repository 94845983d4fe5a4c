"""``POST /sensors/estimate``: a camera's sensitivities estimated from its colour matrices (given as
nine numbers, or read from an uploaded DNG), persisted like an upload (issue 35;
:mod:`sensor_estimate`). The prior is the measured cameras of the service's ``ILLUMIX_SENSOR_PATH``."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, File, Form, UploadFile
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from illumix.engine.library import check_upload_name
from illumix.retarget import sensors as sen
from illumix.retarget.errors import SpectralError
from illumix.service.deps import CtxDep, TokenDep
from illumix.service.errors import error_responses, fail
from illumix.service.models import SensorName

router = APIRouter(tags=["sensors"])
#: a DNG's colour matrices sit in its first IFD, but the file comes whole: bounded apart from uploads
MAX_RAW_BYTES = 64 << 20


class Estimated(BaseModel):
    name: str
    bytes: int = Field(description="size of the stored rawtoaces camera JSON")
    matrices: list[dict] = Field(description="the colour matrices used, with their calibration illuminants")
    prior_cameras: int = Field(description="measured cameras the prior was learned from")
    max_std: float = Field(description="the posterior's largest standard deviation, relative to the peak")


@router.post("/sensors/estimate", status_code=201, response_model=Estimated, dependencies=[TokenDep],
             responses=error_responses(400, 401, 408, 409, 413, 422, 503, 507))
async def estimate_sensor(name: SensorName, ctx: CtxDep,
                          file: Annotated[UploadFile | None, File(description="a DNG")] = None,
                          color_matrix: Annotated[str | None, Form(
                              description="nine numbers, XYZ → camera, rows R, G, B (a DNG's ColorMatrix)",
                              examples=["0.6722,-0.0635,-0.0963,-0.4287,1.2460,0.2028,-0.0908,0.2162,0.5668"])] = None,
                          calibration_illuminant: Annotated[str, Form()] = "D65",
                          color_matrix_2: Annotated[str | None, Form()] = None,
                          calibration_illuminant_2: Annotated[str | None, Form()] = None,
                          overwrite: Annotated[bool, Form()] = False) -> Estimated:
    """Estimate a sensor from ``color_matrix`` (nine numbers, XYZ → camera, rows R, G, B) with its
    ``calibration_illuminant`` (and a second pair), or from a DNG ``file`` (its ColorMatrix1/2), and
    register it under ``name`` (a rawtoaces camera JSON, as ``POST /sensors`` stores)."""
    check_upload_name("sensors", name, sen.builtin_names())
    if name.lower() == "estimate":
        raise SpectralError("'estimate' names this endpoint; choose another sensor name")
    raw = None
    if file is not None:
        raw = await file.read(MAX_RAW_BYTES + 1)
        if len(raw) > MAX_RAW_BYTES:
            raise fail(413, f"the raw file exceeds {MAX_RAW_BYTES >> 20} MiB; send its colour matrices as "
                            "color_matrix= instead", code="too_large")
    doc, summary = await run_in_threadpool(_estimate, name, raw, color_matrix, calibration_illuminant,
                                           color_matrix_2, calibration_illuminant_2)
    data = json.dumps(doc).encode()
    registry = ctx.store.registry("sensors", max_bytes=ctx.limits.max_upload_bytes)
    if name in registry.names() and not overwrite:
        raise fail(409, f"{name!r} exists; send overwrite=true to replace it")
    registry.put(name, data, "json", overwrite=overwrite)
    return Estimated(name=name, bytes=len(data), matrices=doc["header"]["illumix_estimate"]["matrices"],
                     prior_cameras=summary["prior_cameras"], max_std=summary["max_std"])


def _estimate(name: str, raw: bytes | None, cm: str | None, ill: str, cm2: str | None, ill2: str | None):
    from illumix.sensor_estimate.run import EstimateRequest, collect_matrices, run_estimate

    with tempfile.TemporaryDirectory() as d:
        path = None
        if raw is not None:
            path = Path(d) / "upload.dng"
            path.write_bytes(raw)
        matrices, model = collect_matrices(path, cm, ill, cm2, ill2, spell=lambda name: name)
    if not matrices:
        raise SpectralError("give color_matrix (with calibration_illuminant) or a DNG file")
    folders = sen.sensor_dirs()
    if not folders:
        raise SpectralError("this service has no measured cameras to learn a prior from: start it with "
                            "ILLUMIX_SENSOR_PATH pointing at rawtoaces camera JSON files")
    return run_estimate(EstimateRequest(name=name, matrices=matrices, prior=folders, sensor_model=model))
