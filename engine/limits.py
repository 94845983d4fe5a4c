"""Request bounds: every size a client controls has a ceiling that answers 4xx, never an OOM or a hang."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from illumix.store.registry import DEFAULT_MAX_BYTES


class Limits(BaseModel):
    """Service limits (overridable in :func:`service.app.create_app` and by ``illumix serve`` flags)."""

    model_config = ConfigDict(extra="forbid")  # a misspelt limit must not be silently ignored

    max_side: int = Field(4096, ge=1, description="largest output width or height, pixels")
    max_pixels: int = Field(4096 * 4096, ge=1, description="largest output width × height")
    max_batch: int = Field(64, ge=1, description="most samples in one POST /batch")
    max_upload_bytes: int = Field(DEFAULT_MAX_BYTES, ge=1,
                                  description="largest sensor/illuminant upload (the store's registry limit)")
    max_json_bytes: int = Field(1 << 20, ge=1, description="largest JSON request body (POST /batch)")
    max_groups: int = Field(16, ge=1, description="most illuminant entries in one request")
    max_request_mb: int = Field(160, ge=1, description="most working memory one request or batch may need, "
                                                      "MiB (estimated before any work; above it: 413)")
    inflight_mb: int = Field(160, ge=1, description="working memory of all requests being computed or sent "
                                                   "at once, MiB (above it a request waits, then 503)")
    queue_timeout_s: float = Field(30.0, gt=0, description="longest wait for working memory before a 503")
    body_timeout_s: float = Field(10.0, gt=0, description="longest pause while a request body arrives "
                                                         "before a 408")
    body_total_s: float = Field(60.0, gt=0, description="longest time a whole request body may take before a 408")

    @model_validator(mode="after")
    def _consistent(self) -> Limits:
        if self.inflight_mb < self.max_request_mb:
            raise ValueError(f"inflight_mb ({self.inflight_mb}) must be at least max_request_mb "
                             f"({self.max_request_mb}), or the largest allowed request could never run")
        return self
