"""Response models of the JSON endpoints (so ``/openapi.json`` says what each returns)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from illumix.engine.spec import SampleSpec


class CacheStats(BaseModel):
    bytes: int = Field(description="decoded cube bytes held")
    evicted_in_use_bytes: int = Field(description="evicted cubes that requests still use (counted against the bound)")
    max_bytes: int = Field(description="the cache's bound (--cache-mb)")
    hits: int
    misses: int


class MemoryStats(BaseModel):
    inflight_bytes: int = Field(description="working memory reserved by requests being computed or sent")
    inflight_limit_bytes: int
    request_limit_bytes: int
    peak_inflight_bytes: int
    refused_busy: int = Field(description="requests answered 503 because the budget stayed full")


class Health(BaseModel):
    status: str = Field(description="'ok'")
    scenes: int
    cache_bytes: int
    cache_hits: int
    cache_misses: int
    cache: CacheStats
    projections: CacheStats | None = Field(None, description="whole-frame projections kept per (cube, sensor, "
                                                             "illuminant), carved out of --cache-mb; null when off")
    memory: MemoryStats
    auth: bool = Field(description="whether writes need a token")


class GroupInfo(BaseModel):
    name: str
    emission: str = Field(description="emission the cube was rendered with ('flat' = unit, relightable)")
    illumination: bool = Field(False, description="the cube has its illumination cube: the physical ground truth "
                                                  "is served (else the formula's)")
    denoised: str | None = Field(None, description="method of the cube's stored denoised copies (served by default), "
                                                   "null when it has none")


class ViewInfo(BaseModel):
    name: str
    width: int
    height: int
    groups: list[GroupInfo]


class SceneInfo(BaseModel):
    name: str
    views: list[ViewInfo]


class Scenes(BaseModel):
    scenes: list[SceneInfo]


class SensorList(BaseModel):
    builtin: list[str] = Field(description="built-in sensors usable on the store's spectral grid")
    unavailable: dict[str, str] = Field(description="built-in sensors that cannot be used, with the reason")
    uploaded: list[str]


class SensorDetail(BaseModel):
    name: str
    source: str
    grid: dict = Field(description="spectral grid {start, end, step} in nm")
    wavelengths: list[float] = Field(description="band centres, nm")
    sensitivities: list[list[float]] = Field(description="(bands, 3) R, G, B band averages, peak 1")


class KelvinRange(BaseModel):
    min_kelvin: float
    max_kelvin: float


class IlluminantList(BaseModel):
    builtin: list[str]
    parametric: dict[str, KelvinRange] = Field(description="'<kind>:<kelvin>' names, e.g. blackbody:3200")
    uploaded: list[str]


class Uploaded(BaseModel):
    name: str
    format: str = Field(description="'json' (rawtoaces camera) or 'csv'")
    bytes: int


class Deleted(BaseModel):
    deleted: str


class BatchRequest(BaseModel):
    """``POST /batch``: the samples, each with the ``GET /sample`` parameters (``format`` npz or arrays,
    the same for every item)."""

    model_config = ConfigDict(extra="forbid")
    samples: list[SampleSpec] = Field(description="1..max_batch sample specs (the GET /sample parameters)")


class LocusPoint(BaseModel):
    kelvin: float = Field(description="colour temperature, K")
    r_over_g: float = Field(description="R/G of the sensor white point")
    b_over_g: float = Field(description="B/G of the sensor white point")


class IlluminantCurve(BaseModel):
    name: str
    spd: list[float] = Field(description="band-averaged SPD on the grid, scaled to peak 1")
    white_point_rgb: list[float] = Field(description="sensor white point (thesis eq. 3.2), G = 1")
    r_over_g: float
    b_over_g: float


class Spectra(BaseModel):
    """``GET /explore/spectra``: the curves the web explorer plots."""

    sensor: str
    grid: dict = Field(description="spectral grid {start, end, step} in nm")
    wavelengths: list[float] = Field(description="band centres, nm")
    sensitivities: list[list[float]] = Field(description="(bands, 3) R, G, B band averages, peak 1")
    illuminants: list[IlluminantCurve]
    planckian: list[LocusPoint] = Field(description="blackbody white points on this sensor, 1500-20000 K")
    daylight: list[LocusPoint] = Field(description="CIE daylight white points on this sensor, 4000-20000 K")
