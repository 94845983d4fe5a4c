"""The sample request: one pydantic model for GET /sample query parameters and POST /batch items.

Parsing errors are :class:`retarget.errors.SpectralError` with a message saying what to fix; the
app turns them into HTTP 422.
"""

from __future__ import annotations

import re

from pydantic import BaseModel, ConfigDict, Field, field_validator

from retarget.compose import OUTPUTS
from retarget.errors import SpectralError
from retarget.sensor_model import BAYER_PATTERNS, NOISE_PRESETS, NoiseModel

FORMATS = ("npz", "png", "tiff")
EXPOSURE_WORDS = {"auto": "constant", "constant": "constant", "adaptive": "adaptive"}


def _split(value: str | list | None) -> list[str] | None:
    if value is None or isinstance(value, list):
        return value
    items = [v.strip() for v in value.split(",")]
    return [v for v in items if v]


class SampleSpec(BaseModel):
    """What one sample is: which view, lit how, seen by which sensor, cut and encoded how."""

    model_config = ConfigDict(extra="forbid")  # a typo (crops=) must be a 422, not ignored
    scene: str | None = None
    view: str | None = None
    seed: int | None = Field(None, ge=0, le=2**63 - 1)
    sensor: str = "XYZ"
    pair: list[str] | None = None
    illuminants: list[str] | None = None
    intensities: list[float] | None = None
    crop: list[int] | None = None
    size: list[int] | None = None
    outputs: list[str] = Field(default_factory=lambda: list(OUTPUTS) + ["meta"])
    format: str = "npz"
    exposure: str | None = None
    noise: str | None = None
    bayer: str | None = None

    @field_validator("pair", "illuminants", "outputs", mode="before")
    @classmethod
    def _names(cls, v):
        return _split(v)

    @field_validator("intensities", mode="before")
    @classmethod
    def _floats(cls, v):
        items = _split(v)
        if items is None:
            return None
        try:
            return [float(x) for x in items]
        except (TypeError, ValueError):
            raise ValueError("intensities must be comma-separated numbers, e.g. 1,0.5") from None

    @field_validator("crop", mode="before")
    @classmethod
    def _crop(cls, v):
        items = _split(v)
        if items is None:
            return None
        try:
            vals = [int(x) for x in items]
        except (TypeError, ValueError):
            raise ValueError("crop must be x,y,w,h in integer pixels, e.g. 0,0,256,256") from None
        if len(vals) != 4 or vals[0] < 0 or vals[1] < 0 or vals[2] <= 0 or vals[3] <= 0:
            raise ValueError("crop must be x,y,w,h with x,y >= 0 and w,h > 0")
        return vals

    @field_validator("size", mode="before")
    @classmethod
    def _size(cls, v):
        if v is None or isinstance(v, list):
            return v
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(v))
        if not m or int(m[1]) == 0 or int(m[2]) == 0:
            raise ValueError("size must be WxH in pixels, e.g. 256x192")
        return [int(m[1]), int(m[2])]

    @field_validator("format")
    @classmethod
    def _format(cls, v):
        if v not in FORMATS:
            raise ValueError(f"format must be one of {', '.join(FORMATS)}")
        return v

    @field_validator("bayer")
    @classmethod
    def _bayer(cls, v):
        if v is not None and v.upper() not in BAYER_PATTERNS:
            raise ValueError(f"bayer must be one of {', '.join(BAYER_PATTERNS)}")
        return v.upper() if v else None

    @field_validator("outputs")
    @classmethod
    def _outputs(cls, v):
        allowed = set(OUTPUTS) | {"meta"}
        bad = [o for o in v if o not in allowed]
        if bad or not v:
            raise ValueError(f"outputs: unknown {bad}; choose from {', '.join(sorted(allowed))}")
        return v

    # -- derived -----------------------------------------------------------------------------
    def exposure_value(self) -> float | str | None:
        if self.exposure is None:
            return "constant" if self.noise else None  # noise needs raw on the white-level scale
        word = EXPOSURE_WORDS.get(self.exposure.lower())
        if word:
            return word
        try:
            v = float(self.exposure)
        except ValueError:
            raise SpectralError("exposure must be auto, adaptive or a positive number") from None
        if not (v > 0 and v < 1e12):
            raise SpectralError("exposure must be a positive number below 1e12")
        return v

    def noise_model(self) -> NoiseModel | None:
        """``noise=`` is a preset name (low, phone, high) or ``key:value`` pairs, e.g.
        ``full_well:8000;read_noise:3;bit_depth:12`` (separated by ``;`` or ``|``)."""
        if not self.noise or self.noise == "none":
            return None
        if self.noise in NOISE_PRESETS:
            return NOISE_PRESETS[self.noise]
        fields = {}
        for part in re.split(r"[;|]", self.noise):
            key, sep, val = part.partition(":")
            if not sep or key.strip() not in NoiseModel.__dataclass_fields__:
                raise SpectralError(f"noise: {part!r} is not a preset ({', '.join(NOISE_PRESETS)}) or "
                                    f"key:value with key in {', '.join(NoiseModel.__dataclass_fields__)}")
            try:
                fields[key.strip()] = int(val) if key.strip() == "bit_depth" else float(val)
            except ValueError:
                raise SpectralError(f"noise: {key.strip()} must be a number") from None
        return NoiseModel(**fields)

    def array_outputs(self) -> list[str]:
        return [o for o in self.outputs if o != "meta"]
