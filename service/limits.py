"""Request bounds: every size a client controls has a ceiling that answers 422, not an OOM."""

from __future__ import annotations

from pydantic import BaseModel, Field


class Limits(BaseModel):
    """Service limits (overridable in :func:`service.app.create_app`)."""

    max_side: int = Field(4096, description="largest output width or height, pixels")
    max_pixels: int = Field(4096 * 4096, description="largest output width × height")
    max_batch: int = Field(64, description="most samples in one POST /batch")
    max_batch_pixels: int = Field(64 * 1024 * 1024, description="total output pixels in one batch")
    max_upload_bytes: int = Field(2 * 1024 * 1024, description="largest sensor/illuminant upload")
    max_groups: int = Field(16, description="most illuminant entries in one request")
