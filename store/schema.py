"""Metadata schemas (pydantic) of the cube store, with a schema version.

* :class:`CubeMeta` — one per (scene, view, light group) cube: spectral grid, the emission spectrum
  the group was rendered with, renderer provenance, sampling, statistics and the storage encoding.
* :class:`ViewMeta` — one per view: resolution, camera pose and field of view, declared light-group
  order, stored AOVs.

Both accept extra free-form keys (kept verbatim, e.g. ``denoiser="none"``). Stored metadata is read
back with :func:`parse_stored`, which turns every schema problem (newer version, missing attribute,
wrong type) into a one-line :class:`~store.errors.StoreError` naming the node.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone
from typing import Any, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import SpectralGrid
from illumix.store.errors import StoreError

#: Version of the metadata written by this code. Readers refuse anything newer.
SCHEMA_VERSION = 1


def utc_now() -> str:
    """Current UTC time, ISO 8601 with ``Z`` suffix and millisecond resolution."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _check_version(v: int) -> int:
    if v < 1:
        raise ValueError(f"schema_version must be >= 1, got {v}")
    if v > SCHEMA_VERSION:
        raise ValueError(f"schema_version {v} is newer than this illumix reads ({SCHEMA_VERSION}); upgrade illumix")
    return v


class RendererInfo(BaseModel):
    """Renderer provenance: ``name`` (e.g. ``"mitsuba"``), ``backend`` (``"mitsuba"`` or ``"cycles"``;
    empty in stores written before there was a choice: Mitsuba), ``method`` (how the spectrum was
    sampled, e.g. the thesis method's passes of 3 fixed wavelengths), ``version``, ``variant``
    (e.g. ``"llvm_ad_spectral"``) and free-form ``settings`` (max depth, integrator, …)."""

    model_config = ConfigDict(extra="allow")
    name: str = "unknown"
    backend: str = ""
    method: str = ""
    version: str = ""
    variant: str = ""
    settings: dict[str, Any] = Field(default_factory=dict)


class BandStats(BaseModel):
    """Per-band statistics of the cube as written (float32 values before encoding), each a list
    of ``n_bands`` floats in the cube's radiometric units: ``max``, ``mean`` and ``min`` over all
    pixels. Used by ``illumix store verify`` to detect corrupt chunks."""

    max: list[float]
    mean: list[float]
    min: list[float]

    @classmethod
    def of(cls, cube: np.ndarray) -> BandStats:
        """Statistics of a ``(H, W, B)`` cube (mean accumulated in float64)."""
        flat = cube.reshape(-1, cube.shape[-1])
        return cls(max=flat.max(axis=0).astype(float).tolist(),
                   mean=flat.mean(axis=0, dtype=np.float64).tolist(),
                   min=flat.min(axis=0).astype(float).tolist())


class StorageInfo(BaseModel):
    """How a cube's values are stored (set by the store; see :mod:`store.codec`).

    ``dtype``: ``float16`` (exponent-scaled), ``float32`` (raw) or ``none`` (empty group).
    ``band_exponent``: per-band power-of-two exponents β_b (float16 only).
    ``rel_error_bound``: guaranteed ``|x̂ − x| ≤ bound·|x|`` for every value not counted in
    ``underflow_values`` (2⁻¹¹ for float16, 0 for float32).
    ``underflow_values``: values held with an absolute instead of a relative bound (only when
    float16 was forced; ``auto`` falls back to float32 instead).
    """

    dtype: Literal["float16", "float32", "none"]
    encoding: Literal["f16-exp2", "raw", "empty"]
    policy: Literal["auto", "float16", "float32"] = "auto"
    reason: str = ""
    band_exponent: list[int] | None = None
    chunks: list[int] | None = None
    codec: str = ""
    rel_error_bound: float = 0.0
    underflow_values: int = 0
    nbytes_stored: int | None = None


class IlluminationInfo(BaseModel):
    """The illumination cube stored beside a transport cube (DESIGN.md "Physical GT"): per pixel and
    band, the radiance a white Lambertian surface at the first visible point would send to the
    camera, in the transport cube's units, same grid and emission. ``method``: how it was obtained
    (the renderer's ``ILLUMINATION_METHOD``); ``stats``/``storage`` as for the transport cube (filled
    in by the store from the array it is given)."""

    model_config = ConfigDict(extra="allow")
    method: str = ""
    stats: BandStats | None = None
    storage: StorageInfo | None = None


class DenoisedInfo(BaseModel):
    """The denoised copies stored beside a cube (:mod:`retarget.denoise`): ``method``, ``params``,
    ``guides`` (the AOVs its weights come from), ``linear`` (relighting stays exact), ``reference``
    (paper), ``cost_ms`` (filter time for this node's cubes); ``stats``/``storage`` of the denoised
    transport cube and ``illumination_stats``/``illumination_storage`` of the denoised illumination
    cube (filled in by the store). The raw cubes stay as they were rendered."""

    model_config = ConfigDict(extra="allow")
    method: str = ""
    params: dict[str, Any] = Field(default_factory=dict)
    guides: list[str] = Field(default_factory=list)
    linear: bool = True
    reference: str = ""
    cost_ms: float | None = None
    stats: BandStats | None = None
    storage: StorageInfo | None = None
    illumination_stats: BandStats | None = None
    illumination_storage: StorageInfo | None = None


def _grid_dict(v: Any) -> dict[str, float]:
    if isinstance(v, SpectralGrid):
        return v.to_dict()
    if not isinstance(v, dict):
        raise ValueError("grid must be a SpectralGrid or a dict with start, end, step (nm)")
    try:
        return SpectralGrid.from_dict(v).to_dict()
    except (KeyError, TypeError, ValueError, SpectralError) as exc:
        raise ValueError(f"invalid grid {v!r}: {exc}") from None


class CubeMeta(BaseModel):
    """Metadata of one transport cube ``(H, W, n_bands)``.

    ``grid``: the spectral grid (``SpectralGrid`` or dict ``start``/``end``/``step`` in nm).
    ``emission``: the group's emission spectrum as band averages on ``grid`` (relative units;
    ``n_bands`` non-negative floats). Default: flat/unit (all ones), with ``emission_name="flat"``.
    ``renderer``: :class:`RendererInfo`. ``spp``: samples per pixel. ``seed``: RNG seed.
    ``scene_hash``: hash of the scene description. ``created``: UTC ISO time (set on write).
    ``stats`` and ``storage`` are filled in by :meth:`store.CubeStore.write_cube`.
    ``empty``: the group contributes nothing to this view (no array stored; reads give zeros).
    ``illumination``: :class:`IlluminationInfo` when the node also holds the illumination cube
    (``None`` in stores rendered before it existed: the service then serves the formula ground truth).
    ``denoised``: :class:`DenoisedInfo` when the node also holds denoised copies of its cubes.
    ``group_kind``: ``"daylight"`` or ``"artificial"`` when the scene declares (or its emitters show)
    what kind of light the group is; ``None`` (stores rendered before it existed, or unknown): the
    service infers it where it can (:mod:`engine.lighting`).
    """

    model_config = ConfigDict(extra="allow")
    schema_version: int = SCHEMA_VERSION
    grid: dict[str, float]
    emission: list[float] | None = None
    emission_name: str = "flat"
    renderer: RendererInfo = Field(default_factory=RendererInfo)
    spp: int | None = Field(default=None, ge=0)
    seed: int | None = None
    scene_hash: str = ""
    created: str | None = None
    stats: BandStats | None = None
    storage: StorageInfo | None = None
    empty: bool = False
    illumination: IlluminationInfo | None = None
    denoised: DenoisedInfo | None = None
    group_kind: Literal["daylight", "artificial"] | None = None

    _v = field_validator("schema_version")(_check_version)

    @field_validator("grid", mode="before")
    @classmethod
    def _grid(cls, v: Any) -> dict[str, float]:
        return _grid_dict(v)

    @field_validator("emission", mode="before")
    @classmethod
    def _emission(cls, v: Any) -> Any:
        return np.asarray(v, dtype=float).ravel().tolist() if isinstance(v, np.ndarray) else v

    @model_validator(mode="after")
    def _fill(self) -> CubeMeta:
        n = self.spectral_grid.n_bands
        if self.emission is None:
            self.emission = [1.0] * n
        if len(self.emission) != n:
            raise ValueError(f"emission has {len(self.emission)} values but the grid has {n} bands")
        if not all(math.isfinite(e) and e >= 0 for e in self.emission):
            raise ValueError("emission must be finite and non-negative (band averages, relative units)")
        dn = self.denoised
        for s in (self.stats, self.illumination.stats if self.illumination else None,
                  dn.stats if dn else None, dn.illumination_stats if dn else None):
            if s is not None and not (len(s.max) == len(s.mean) == len(s.min) == n):
                raise ValueError(f"stats must have {n} values per statistic (one per band)")
        return self

    @property
    def spectral_grid(self) -> SpectralGrid:
        """The grid as a :class:`retarget.grid.SpectralGrid`."""
        return SpectralGrid.from_dict(self.grid)

    @property
    def n_bands(self) -> int:
        return self.spectral_grid.n_bands


Vec3 = tuple[float, float, float]


class ViewMeta(BaseModel):
    """Metadata of one camera view.

    ``width``, ``height``: resolution in pixels (every cube and AOV of the view is
    ``(height, width, …)``). ``origin``, ``target``, ``up``: camera look-at pose in scene units
    (``None`` when unknown, e.g. imported cubes). ``fov``: field of view in degrees along
    ``fov_axis`` (``"x"`` horizontal, ``"y"`` vertical). ``groups``: the declared light-group
    order (:meth:`store.CubeStore.groups` lists groups in this order; undeclared ones follow in
    order of first write). ``aovs``: AOV names stored (set by the store). Extra keys are kept.
    """

    model_config = ConfigDict(extra="allow")
    schema_version: int = SCHEMA_VERSION
    width: int = Field(gt=0, le=65536)
    height: int = Field(gt=0, le=65536)
    origin: Vec3 | None = None
    target: Vec3 | None = None
    up: Vec3 | None = None
    fov: float | None = Field(default=None, gt=0, lt=180)
    fov_axis: Literal["x", "y"] = "x"
    groups: list[str] = Field(default_factory=list)
    aovs: list[str] = Field(default_factory=list)
    created: str | None = None

    _v = field_validator("schema_version")(_check_version)


M = TypeVar("M", bound=BaseModel)


def parse_stored(model: type[M], raw: Any, where: str, required: tuple[str, ...] = ()) -> M:
    """Validate metadata read from ``where`` (a node path) into ``model``.

    Raises :class:`StoreError` for a missing attribute, a newer schema version or invalid fields;
    ``required`` names keys that must be present even though the model has defaults for them.
    """
    if not isinstance(raw, dict):
        raise StoreError(f"missing metadata attribute in {where}; the node is corrupt or not written by "
                         "illumix (run `illumix store verify` and rewrite it)")
    v = raw.get("schema_version")
    if v is None:
        raise StoreError(f"missing attribute 'schema_version' in {where}; rewrite this node")
    if isinstance(v, int) and v > SCHEMA_VERSION:
        raise StoreError(f"{where} has schema version {v}, newer than this illumix reads "
                         f"({SCHEMA_VERSION}); upgrade illumix")
    missing = [k for k in required if k not in raw or raw[k] is None]
    if missing:
        raise StoreError(f"missing attribute {missing[0]!r} in {where}; rewrite this node "
                         "(run `illumix store verify` to list every problem)")
    try:
        return model.model_validate(raw)
    except ValidationError as exc:
        e = exc.errors()[0]
        loc = ".".join(str(p) for p in e["loc"]) or "(root)"
        kind = "missing attribute" if e["type"] == "missing" else "invalid attribute"
        raise StoreError(f"{kind} {loc!r} in {where}: {e['msg']}; rewrite this node") from None
