"""Scene description, part 0: the names, the base model and the spectrum specs every other part
uses (split from :mod:`scene.schema` so that textures, which mix spectra, can be
described beside them without an import cycle)."""

from __future__ import annotations

from typing import Annotated, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator

from illumix.scene.migrate import CURRENT as SCHEMA_VERSION  # noqa: F401 - re-exported: the format's version

NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.+\-]*$"  # the cube store's name rules (no "..", see below)


class SceneError(ValueError):
    """A bad scene description: one line naming the file, the object and the field."""


Vec3 = tuple[float, float, float]


def _no_dotdot(v: str) -> str:
    if ".." in v:
        raise ValueError(f"name {v!r} must not contain '..'")
    return v


Name = Annotated[str, Field(pattern=NAME_PATTERN, max_length=100), AfterValidator(_no_dotdot)]


class StrictModel(BaseModel):
    """Base of every scene model: unknown fields are errors, instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True)


# ---------------------------------------------------------------------------------------------
# Spectra


class LibrarySpectrum(StrictModel):
    """A reflectance from a :mod:`retarget.reflectances` set: by 0-based ``index`` or ``sample`` name."""

    library: str
    index: int | None = Field(default=None, ge=0)
    sample: str | None = None

    @model_validator(mode="after")
    def _one_key(self) -> LibrarySpectrum:
        if (self.index is None) == (self.sample is None):
            raise ValueError("give exactly one of 'index' (0-based) or 'sample' (name)")
        return self


class FileSpectrum(StrictModel):
    """A CSV file ``wavelength,value[,value…]``; ``column`` picks a value column (0-based)."""

    file: str
    column: int = Field(default=0, ge=0)


class TableSpectrum(StrictModel):
    """An inline table of ``wavelengths`` (nm) and ``values``."""

    wavelengths: list[float] = Field(min_length=2)
    values: list[float] = Field(min_length=2)

    @model_validator(mode="after")
    def _same_length(self) -> TableSpectrum:
        if len(self.wavelengths) != len(self.values):
            raise ValueError(f"{len(self.wavelengths)} wavelengths but {len(self.values)} values")
        return self


class ConstantSpectrum(StrictModel):
    """The same value at every wavelength."""

    value: float = Field(ge=0)


SpectrumSpec = Union[LibrarySpectrum, FileSpectrum, TableSpectrum, ConstantSpectrum]
