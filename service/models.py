"""Response models of the JSON endpoints (so ``/openapi.json`` says what each returns), and the upload
forms' ``name`` and ``file`` fields (so it says what each accepts: the name rule as a pattern)."""

from __future__ import annotations

import math
import re
from typing import Annotated

from fastapi import File, Form, UploadFile
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from illumix.engine.spec import SampleSpec
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.store import StoreError
from illumix.store.names import MAX_NAME_LEN, check_name


# -- upload names ------------------------------------------------------------------------------------
def _literal(name: str) -> str:
    """``name`` (letters, digits, ``_ . + -``) as an ECMA-262 pattern: only ``.`` and ``+`` need escapes."""
    return name.replace(".", "\\.").replace("+", "\\+")


def _nocase(word: str) -> str:
    return "".join(f"[{c.upper()}{c.lower()}]" if c.isalpha() else _literal(c) for c in word)


def _not(names) -> str:
    """An ECMA-262 negative lookahead refusing ``names`` in any case (lookups ignore case, so an
    upload named ``d65`` would never be served: :func:`engine.library.check_upload_name`)."""
    return "(?!(?:" + "|".join(_nocase(n) for n in names) + ")$)"


#: :func:`store.names.check_name` as an ECMA-262 pattern: letters, digits, ``_ . + -``, starting with
#: a letter or digit, no ``..``, not ``zarr.json`` nor ``*.partial`` (any case).
NAME_PATTERN = (f"(?!{_nocase('zarr.json')}$)(?!.*{_nocase('.partial')}$)"
                r"[A-Za-z0-9](?:\.?[A-Za-z0-9_+\-])*\.?$")
#: built-in names an upload may not take (the server compares ignoring case, as here; names with other
#: characters are refused by the pattern anyway). The cameras of ILLUMIX_SENSOR_PATH are read when the
#: service runs, so the sensor pattern names only XYZ.
_ILLUMINANT_TAKEN = [n for n in ill.builtin_names() if re.fullmatch(r"[A-Za-z0-9_.+-]+", n)]
SENSOR_NAME_PATTERN = f"^(?!{_nocase('estimate')}$){_not([sen.XYZ])}{NAME_PATTERN}"
ILLUMINANT_NAME_PATTERN = f"^{_not(_ILLUMINANT_TAKEN)}{NAME_PATTERN}"


def _store_name(kind: str):
    def check(name: str) -> str:
        try:
            return check_name(name, kind)
        except StoreError as exc:
            raise ValueError(str(exc)) from None
    return check


def _csv(header: str, row) -> str:
    return header + "\n" + "\n".join(f"{w}," + ",".join(f"{v:.3f}" for v in row(w)) for w in range(380, 781, 20))


def _bell(w: float, centre: float, width: float) -> float:
    return math.exp(-(((w - centre) / width) ** 2))


#: what the upload forms' ``file`` examples hold: a smooth SPD rising to the red, and three bell curves
ILLUMINANT_CSV_EXAMPLE = _csv("wavelength,value", lambda w: (0.25 + 0.75 * (w - 380) / 400,))
SENSOR_CSV_EXAMPLE = _csv("wavelength,r,g,b", lambda w: (_bell(w, 600, 40), _bell(w, 540, 40), _bell(w, 460, 30)))
SensorFile = Annotated[UploadFile, File(
    description="a rawtoaces camera JSON, or a CSV `wavelength,r,g,b` (nm, non-negative, resampled onto the "
                "spectral grid); at most the service's upload limit (1 MiB by default)",
    examples=[SENSOR_CSV_EXAMPLE])]
IlluminantFile = Annotated[UploadFile, File(
    description="a CSV `wavelength,value` (nm, non-negative, any scale, resampled onto the spectral grid); at "
                "most the service's upload limit (1 MiB by default)",
    examples=[ILLUMINANT_CSV_EXAMPLE])]

_NAME_RULE = (f"1-{MAX_NAME_LEN} letters, digits, _ . + -, starting with a letter or digit, without '..', not "
              "zarr.json or *.partial")
SensorName = Annotated[str, Form(
    min_length=1, max_length=MAX_NAME_LEN, examples=["my-camera"],
    description=f"the sensor's name: {_NAME_RULE}, not 'estimate' and not a built-in sensor's name (GET "
                "/sensors lists them; measured cameras of ILLUMIX_SENSOR_PATH included)",
    json_schema_extra={"pattern": SENSOR_NAME_PATTERN}), AfterValidator(_store_name("sensor"))]
IlluminantName = Annotated[str, Form(
    min_length=1, max_length=MAX_NAME_LEN, examples=["my-lamp"],
    description=f"the illuminant's name: {_NAME_RULE}, and not a built-in illuminant's name (GET /illuminants "
                "lists them)",
    json_schema_extra={"pattern": ILLUMINANT_NAME_PATTERN}), AfterValidator(_store_name("illuminant"))]


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
    width: int | None = Field(description="pixels; null for a damaged view")
    height: int | None = Field(description="pixels; null for a damaged view")
    groups: list[GroupInfo]
    damaged: str | None = Field(None, description="why the view cannot be served (its metadata or a group's "
                                                  "is damaged: `illumix store verify` lists it); null when healthy")


class SceneInfo(BaseModel):
    name: str
    views: list[ViewInfo]
    damaged: str | None = Field(None, description="why the scene cannot be listed; null when healthy")


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
    builtin: list[str] = Field(description="built-in (tabulated) illuminants usable on the store's spectral grid")
    unavailable: dict[str, str] = Field(
        default_factory=dict, description="built-in illuminants that cannot be used (their tables stop short of the "
                                          "grid, e.g. ISO 7589), with the reason")
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

    # the example suits any store whose views are at least 16x16 pixels (no pair=: views differ in groups)
    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [{"samples": [
        {"seed": 1, "crop": "0,0,16,16"}, {"seed": 2, "sensor": "XYZ", "outputs": "raw,meta", "size": "32x24"}]}]})
    samples: list[SampleSpec] = Field(description="1..max_batch sample specs (the GET /sample parameters; "
                                                  "max_batch is the service's limit, 64 by default)",
                                      json_schema_extra={"minItems": 1})


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
