"""The sample request: one pydantic model for GET /sample query parameters and POST /batch items.

The wire form is the query-string form (``pair=A,D65``, ``crop=0,0,256,256``, ``size=256x192``);
JSON batch items may also give lists (``"pair": ["A", "D65"]``, ``"size": [256, 192]``). Unknown
parameters are refused (``extra="forbid"``), so a typo such as ``crops=`` is a 422 naming ``crop``,
never silently ignored. Field validation errors become 422 answers through
:mod:`service.errors`; derived values that need the library (noise, exposure) raise
:class:`retarget.errors.SpectralError`, also a 422.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    WithJsonSchema,
    field_validator,
    model_validator,
)

from illumix.retarget.compose import OUTPUTS
from illumix.retarget.denoise_methods import DENOISE_CHOICES
from illumix.retarget.errors import SpectralError, UnknownName
from illumix.retarget.exposure import EXPOSURE_METHODS
from illumix.retarget.sensor_model import BAYER_PATTERNS, NOISE_PRESETS, NoiseModel

FORMATS = ("npz", "arrays", "png", "tiff", "dng", "exr")
AOV_OUTPUTS = ("albedo", "normal", "depth")  # the view's geometry AOVs, as stored
SPECTRAL_OUTPUTS = frozenset({"reflectance", "illumination"})  # per-pixel spectra over the bands
# The user's four (raw, gain map, CCM map, sRGB) and the rest of the ground truth. ccm is 36 bytes a
# pixel (25 MB of a 56 MB 720x960 float32 answer): dtype=float16 halves it, and it is exactly
# Σ_g mixture_g CCM_g from the mixture output and meta["illuminants"][g]["ccm"], so a client short of
# bandwidth may leave it out (outputs=...) and rebuild it (illumix_client.Sample.ccm_map()).
DEFAULT_OUTPUTS = (*OUTPUTS, "meta")
ALL_OUTPUTS = (*OUTPUTS, *AOV_OUTPUTS, "reflectance", "illumination", "meta")
CAMERA_NOISE = "camera"  # noise=camera: the sensor's own model (a DNG's levels and NoiseProfile)
MAX_NAME = 256  # longest scene/view/sensor/illuminant name accepted (close-match search is O(n·m))

#: The outputs each single-image format can carry (one per answer).
IMAGE_OUTPUTS = {"png": ("raw", "gain", "srgb", "mask"), "tiff": ("raw", "gain", "srgb", "mask", "weights"),
                 "dng": ("raw",)}


def _items(v: Any, what: str) -> list[str] | None:
    """Comma-separated text, or a list of items (each possibly comma-separated) → stripped items."""
    if v is None:
        return None
    parts = v if isinstance(v, list) else [v]
    out = []
    for p in parts:
        if isinstance(p, bool) or not isinstance(p, (str, int, float)):
            raise ValueError(f"{what} must be comma-separated text, e.g. {_EXAMPLES[what]}")
        out.extend(x.strip() for x in str(p).split(","))
    return [x for x in out if x]


def _names(what: str):
    def check(v: Any) -> list[str] | None:
        items = _items(v, what)
        if items is not None and any(len(x) > MAX_NAME for x in items):
            raise ValueError(f"{what}: names are at most {MAX_NAME} characters")
        return items
    return check


def _floats(v: Any) -> list[float] | None:
    items = _items(v, "intensities")
    if items is None:
        return None
    try:
        vals = [float(x) for x in items]
    except ValueError:
        raise ValueError("intensities must be comma-separated numbers, e.g. 1,0.5") from None
    if not all(np.isfinite(x) and 0 <= x <= 1e9 for x in vals):
        raise ValueError("intensities must be finite numbers between 0 and 1e9")
    return vals


def _ints(what: str, n: int, example: str):
    def check(v: Any) -> list[int] | None:
        if v is None:
            return None
        if what == "size" and isinstance(v, (str, list)) and len(v) == 1 and isinstance(v[0], str):
            v = v[0]  # one query value
        if what == "size" and isinstance(v, str):
            m = re.fullmatch(r"\s*(\d{1,6})\s*[xX]\s*(\d{1,6})\s*", v)
            if not m:
                raise ValueError(f"size must be WxH in pixels, e.g. {example}")
            vals = [int(m[1]), int(m[2])]
        else:
            texts = [x for x in (v if isinstance(v, list) else [v]) if isinstance(x, str)]
            if any(not x.strip() for t in texts for x in t.split(",")):  # "0,0,1,1," or "0,,1,1"
                raise ValueError(f"{what} must be {n} comma-separated integers with nothing between two commas "
                                 f"or after the last, e.g. {example}")
            items = v if isinstance(v, list) and all(isinstance(x, int) and not isinstance(x, bool) for x in v) \
                else _items(v, what)
            try:
                vals = [int(x) if isinstance(x, int) else int(str(x), 10) for x in items]
            except ValueError:
                raise ValueError(f"{what} must be {n} integers, e.g. {example}") from None
        if len(vals) != n or any(x < 0 or x > 10**6 for x in vals):
            raise ValueError(f"{what} must be {n} integers between 0 and 1e6, e.g. {example}")
        if what == "size" and 0 in vals:
            raise ValueError(f"size must be at least 1x1 pixels, e.g. {example}")
        if what == "crop" and (vals[2] == 0 or vals[3] == 0):
            raise ValueError(f"crop must be x,y,w,h with w,h > 0, e.g. {example}")
        return vals
    return check


def _seed(v: Any) -> Any:
    # Lax int parsing would take 1.0, "1.0" and True as seed 1; a seed is an exact integer.
    if v is None or (isinstance(v, int) and not isinstance(v, bool)):
        return v
    if isinstance(v, str) and re.fullmatch(r"\d{1,19}", v.strip()):
        return int(v)
    raise ValueError(f"seed must be a non-negative integer, e.g. 7; got {v!r}")


_EXAMPLES = {"pair": "A,D65", "illuminants": "FL11,D50", "outputs": "raw,gain,meta",
             "intensities": "1,0.5", "crop": "0,0,256,256", "size": "256x192"}


def _text(description: str, example: str | None = None, pattern: str | None = None) -> WithJsonSchema:
    """A text parameter's schema. ``example``: only where it suits every store — the OpenAPI examples of
    a route are sent together, so they must make one valid request on any view of at least 16x16
    pixels (pair= and intensities= depend on the view's light groups: their examples are in words)."""
    schema: dict[str, Any] = {"type": "string", "description": description}
    if example is not None:
        schema["examples"] = [example]
    if pattern:
        schema["pattern"] = pattern
    return WithJsonSchema(schema)


def _nocase(word: str) -> str:
    return "".join(f"[{c.upper()}{c.lower()}]" for c in word)


# The schema's patterns state what the validators accept (ASCII digits and ECMA-262 whitespace; the
# server's Python parsing also takes other Unicode digits and whitespace, and 1_000): comma-separated
# items (empty ones dropped) — outputs by name, exactly two illuminants for pair=, numbers for
# intensities= (their range is in words) —, a size of 1..6 digits per side and not 0, a crop whose
# width and height are not 0.
def _listed(item: str, count: str = "*") -> str:
    return rf"^[\s,]*{item}(?:\s*,[\s,]*{item}){count}[\s,]*$"


_ITEM = r"[^\s,](?:[^,]*[^\s,])?"
_NUMBER = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
_OUTPUTS_PATTERN = _listed("(?:" + "|".join(ALL_OUTPUTS) + ")")
_SIZE_PATTERN = r"^\s*(?!0+\s*[xX])\d{1,6}\s*[xX]\s*(?!0+\s*$)\d{1,6}\s*$"
_CROP_PATTERN = r"^\s*\d+\s*,\s*\d+\s*,\s*0*[1-9]\d*\s*,\s*0*[1-9]\d*\s*$"
#: what ``exposure``'s enforced pattern and its validator accept together: a method (any case) or a
#: number that is not 0 (the validator's upper bound, 1e12, is left to it)
_EXPOSURE_PATTERN = (r"^\s*(" + "|".join(_nocase(m) for m in EXPOSURE_METHODS.choices())
                     + r"|(?![0.]*([eE][+-]?[0-9]+)?\s*$)[0-9]*\.?[0-9]+([eE][+-]?[0-9]+)?)\s*$")

Outputs = Annotated[list[str], BeforeValidator(_names("outputs")),
                    _text(f"comma-separated subset of {', '.join(ALL_OUTPUTS)} (default: {', '.join(DEFAULT_OUTPUTS)})",
                          "raw,gain,meta", _OUTPUTS_PATTERN)]


class SampleSpec(BaseModel):
    """What one sample is: which view, lit how, seen by which sensor, cut and encoded how."""

    model_config = ConfigDict(extra="forbid")  # a typo (crops=) must be a 422, not ignored

    scene: str | None = Field(None, max_length=MAX_NAME, description="scene name (random when omitted)")
    view: str | None = Field(None, max_length=MAX_NAME, description="view name (random when omitted)")
    seed: Annotated[int | None, BeforeValidator(_seed)] = Field(
        None, ge=0, le=2**63 - 1, examples=[7],
        description="seed for the random choices and the noise (random when omitted)")
    sensor: str = Field("XYZ", min_length=1, max_length=MAX_NAME, examples=["XYZ"],
                        description="built-in or uploaded sensor name; random: a camera drawn with the seed from "
                                    "the prior of the measured cameras (random:<seed> names one)")
    pair: Annotated[list[str] | None, BeforeValidator(_names("pair")),
                    _text("two illuminants, e.g. A,D65. Where the view's groups have kinds (declared, from the "
                          "emission they were rendered with, or a daylight name such as daylight, sun, sky) and "
                          "exactly one of the two is daylight (D-series, daylight:<K>, or CCT above 4500 K), it "
                          "lights every daylight group and the other every artificial group, in either order; "
                          "otherwise the first lights the view's first group, the second its second, others "
                          "off. meta.lighting_rule says which rule applied and each group's kind and "
                          "illuminant (a view with one light group refuses pair=: use illuminants=)",
                          pattern=_listed(_ITEM, "{1}"))] = None
    illuminants: Annotated[list[str] | None, BeforeValidator(_names("illuminants")),
                           _text("one illuminant per light group, in the view's group order, e.g. FL11,D50 "
                                 "for a view with two (never reordered by kind)",
                                 pattern=_listed(_ITEM))] = None
    intensities: Annotated[list[float] | None, BeforeValidator(_floats),
                           _text("one intensity per lit group (default 1), 0..1e9, e.g. 1,0.5 for two; with "
                                 "pair=, two values go with the pair's illuminants in its order",
                                 pattern=_listed(_NUMBER))] = None
    crop: Annotated[list[int] | None, BeforeValidator(_ints("crop", 4, "0,0,256,256")),
                    _text("x,y,w,h in pixels, inside the view's frame", "0,0,16,16", _CROP_PATTERN)] = None
    size: Annotated[list[int] | None, BeforeValidator(_ints("size", 2, "256x192")),
                    _text("WxH output size in pixels (area resampling)", "32x24", _SIZE_PATTERN)] = None
    outputs: Outputs = Field(default_factory=lambda: list(DEFAULT_OUTPUTS))
    gt: Annotated[Literal["physical", "formula"] | None, BeforeValidator(lambda v: v.lower() if isinstance(v, str) else v)] = Field(
        None, description="ground truth: physical (from the illumination cubes, bounce light included; the "
                          "default where the store has them) or formula (thesis eq. 3.3)")
    denoise: str | None = Field(
        None, max_length=MAX_NAME,
        description=f"none (the cubes as rendered) or a denoise method ({', '.join(DENOISE_CHOICES.names[1:])}): "
                    "the cubes' stored denoised copies (guide-only, linear: relighting stays exact). Default: the "
                    "stored copies where every lit group has them, else none")
    format: Literal["npz", "arrays", "png", "tiff", "dng", "exr"] = Field(
        "npz", description="npz (all outputs), arrays (all outputs, the flat illumix container: faster; "
                           "application/x-illumix-arrays), png/tiff (one image output), dng (outputs=raw: a "
                           "Bayer DNG, bayer= or RGGB; bayer=none: a LinearRaw DNG) or exr (all outputs, one float32 OpenEXR, a layer each)")
    dtype: Literal["float32", "float16"] = Field(
        "float32", description="float outputs as float32, or as float16 with a power-of-two scale per output "
                               "(value = stored × scale; meta.encoding.scales); npz and arrays only")
    exposure: str | None = Field(None, max_length=32, description="auto, adaptive or a positive gain",
                                 pattern=r"^\s*([A-Za-z]+|[0-9]*\.?[0-9]+([eE][+-]?[0-9]+)?)\s*$",
                                 json_schema_extra={"pattern": _EXPOSURE_PATTERN})
    noise: str | None = Field(None, max_length=512, description="low, phone, high, key:value;… "
                                                                "(full_well, read_noise, black_level, white_level, bit_depth), "
                                                                "or camera: the sensor's own model, from the DNG it was "
                                                                "estimated from (illumix sensors estimate --from-raw)")
    bayer: str | None = Field(None, description="RGGB, BGGR, GRBG or GBRG (any case): the raw as that mosaic; "
                                                "none: no mosaic (as omitted; format=dng: a LinearRaw RGB DNG)",
                              pattern=r"^([Rr][Gg][Gg][Bb]|[Bb][Gg][Gg][Rr]|[Gg][Rr][Bb][Gg]|[Gg][Bb][Rr][Gg]|[Nn][Oo][Nn][Ee])$")

    @field_validator("outputs")
    @classmethod
    def _outputs(cls, v: list[str]) -> list[str]:
        bad = [o for o in v if o not in ALL_OUTPUTS]
        if bad or not v:
            raise ValueError(f"unknown output(s) {bad}; choose from {', '.join(ALL_OUTPUTS)}")
        return list(dict.fromkeys(v))

    @model_validator(mode="after")
    def _one_image(self) -> SampleSpec:
        if self.dtype != "float32" and self.format not in ("npz", "arrays"):
            how = "is float32, exact" if self.format == "exr" else "has its own fixed scale"
            raise ValueError(f"dtype={self.dtype} is for format=npz or arrays; format={self.format} {how}: drop "
                             "dtype= or ask format=arrays")
        if self.format == "dng" and "outputs" not in self.model_fields_set:
            self.outputs = ["raw", "meta"]  # a DNG holds the raw: nothing else to choose
        images = [o for o in self.outputs if o != "meta"]
        if self.format in IMAGE_OUTPUTS and (len(images) != 1 or images[0] not in IMAGE_OUTPUTS[self.format]):
            example = "raw" if self.format == "dng" else "srgb"
            raise ValueError(f"format={self.format} returns exactly one image output, one of "
                             f"{', '.join(IMAGE_OUTPUTS[self.format])}; ask e.g. outputs={example}&format={self.format}")
        if self.format == "exr" and not images:
            raise ValueError("format=exr writes array outputs (meta goes in its header); ask e.g. outputs=raw,gain,meta")
        return self

    @field_validator("denoise")
    @classmethod
    def _denoise(cls, v: str | None) -> str | None:
        return None if v is None else _known(DENOISE_CHOICES, v)

    @field_validator("bayer")
    @classmethod
    def _bayer(cls, v: str | None) -> str | None:
        return None if v is None or v.lower() == "none" else _known(BAYER_PATTERNS, v)

    @field_validator("exposure")
    @classmethod
    def _exposure(cls, v: str | None) -> str | None:
        if v is None or v in EXPOSURE_METHODS:
            return v
        try:
            gain = float(v)
        except ValueError:
            raise ValueError(f"exposure must be {', '.join(EXPOSURE_METHODS.choices())} or a positive number") from None
        if not (0 < gain < 1e12):
            raise ValueError("exposure must be a positive number below 1e12")
        return v

    @field_validator("noise")
    @classmethod
    def _noise(cls, v: str | None) -> str | None:
        if v is not None:
            parse_noise(v)
        return v

    # -- derived -----------------------------------------------------------------------------
    def exposure_value(self) -> float | str | None:
        """``None`` (relative units), an AEC method name or a gain. Noise needs raw on the
        white-level scale, so it implies auto exposure."""
        if self.exposure is None:
            return "constant" if self.noise else None
        if self.exposure in EXPOSURE_METHODS:
            return EXPOSURE_METHODS.canonical(self.exposure)
        return float(self.exposure)

    def noise_model(self) -> NoiseModel | None:
        """The noise model named here (``noise=camera`` needs the sensor: :attr:`engine.plan.Plan.noise`)."""
        if self.noise is not None and self.noise.strip().lower() == CAMERA_NOISE:
            raise SpectralError("noise=camera is the sensor's own model: resolve it with the plan (Plan.noise)")
        return None if self.noise is None else parse_noise(self.noise)

    def array_outputs(self) -> list[str]:
        return [o for o in self.outputs if o != "meta"]


def _known(registry, value: str) -> str:
    try:
        return registry.canonical(value)
    except UnknownName as exc:
        raise ValueError(str(exc)) from None


def parse_noise(text: str) -> NoiseModel | None:
    """``noise=`` is ``none``, a preset name (low, phone, high) or ``key:value`` pairs, e.g.
    ``full_well:8000;read_noise:3;bit_depth:12`` (separated by ``;`` or ``|``)."""
    if not text.strip() or text.strip().lower() == "none":
        return None
    if text.strip().lower() == CAMERA_NOISE:
        return None  # the sensor's own: resolved with the plan (engine.plan)
    if text in NOISE_PRESETS:
        return NOISE_PRESETS[text]
    fields: dict[str, Any] = {}
    keys = NoiseModel.__dataclass_fields__
    for part in re.split(r"[;|]", text):
        key, sep, val = (p.strip() for p in part.partition(":"))
        if not sep or key not in keys:
            raise SpectralError(f"noise: {part.strip()!r} is not a preset ({', '.join(NOISE_PRESETS.choices())}) "
                                f"or key:value with key in {', '.join(keys)}")
        try:
            fields[key] = int(val) if key == "bit_depth" else float(val)
        except ValueError:
            raise SpectralError(f"noise: {key} must be a {'whole ' if key == 'bit_depth' else ''}number, "
                                f"got {val!r}") from None
    return NoiseModel(**fields)
