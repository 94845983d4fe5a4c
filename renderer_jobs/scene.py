"""Scene description: shapes, materials, light groups and views, loaded from YAML/JSON.

This is the renderer-independent description of a scene (pydantic v2). The Mitsuba backend
(:mod:`renderer_jobs.mitsuba_backend`) turns it into a Mitsuba scene; nothing here imports Mitsuba.

Conventions
-----------
- Right-handed world coordinates in metres, +y up.
- Spectra (reflectances, emission) enter the renderer as **band averages on the scene's spectral
  grid** (default 395–705 nm / 5 nm, DESIGN.md), i.e. piecewise-constant over each band. A cube
  band is then exactly ``Ē_g · T`` and relighting by ``Φ̄_g / Ē_g`` (DESIGN.md "The key idea") is exact
  by construction.
- Emitter strengths are *geometric*: they scale a light group's emission spectrum ``E_g`` (flat, value
  1, unless the group names another spectrum). Units: ``area`` and ``constant`` sky — radiance;
  ``point`` and ``spot`` — intensity (per steradian); ``directional`` sun — irradiance on a plane
  perpendicular to the light; ``envmap`` — a multiplier on the map's luminance.
- Shapes follow Mitsuba's canonical forms: ``rectangle`` is ``[-1, 1]²`` in the z = 0 plane with normal
  +z; ``disk`` the unit disk at z = 0 with normal +z; ``cube`` ``[-1, 1]³``; ``sphere`` and ``cylinder`` are
  given by centre/radius and end points/radius; ``obj``/``ply`` meshes by file (paths relative to the
  scene file). Each shape may carry a ``transform`` (scale → rotate → translate, or a 4×4 matrix).

A file holds one scene, or ``{scenes: [...]}`` several. Loading validates everything — names that
must resolve (materials, light groups, library spectra, files) included — and reports every problem
as ``<file>: <object path> (<name>): <field>: <what is wrong>`` on one line.
"""

from __future__ import annotations

import hashlib
import json
import math
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
import yaml
from pydantic import (AfterValidator, BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator,
                      model_validator)

from retarget.errors import SpectralError
from retarget.grid import SpectralGrid
from retarget.illuminants import spd_from_samples
from retarget.illuminants import illuminant_spd as _library_spd

NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.+\-]*$"  # the cube store's name rules (no "..", see below)
SCHEMA_VERSION = 1


class SceneError(ValueError):
    """A bad scene description: one line naming the file, the object and the field."""


Vec3 = tuple[float, float, float]
def _no_dotdot(v: str) -> str:
    if ".." in v:
        raise ValueError(f"name {v!r} must not contain '..'")
    return v


Name = Annotated[str, Field(pattern=NAME_PATTERN, max_length=100), AfterValidator(_no_dotdot)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# ---------------------------------------------------------------------------------------------
# Spectra


class LibrarySpectrum(_Model):
    """A reflectance from a :mod:`retarget.reflectances` set: by 0-based ``index`` or ``sample`` name."""

    library: str
    index: int | None = Field(default=None, ge=0)
    sample: str | None = None

    @model_validator(mode="after")
    def _one_key(self) -> LibrarySpectrum:
        if (self.index is None) == (self.sample is None):
            raise ValueError("give exactly one of 'index' (0-based) or 'sample' (name)")
        return self


class FileSpectrum(_Model):
    """A CSV file ``wavelength,value[,value…]``; ``column`` picks a value column (0-based)."""

    file: str
    column: int = Field(default=0, ge=0)


class TableSpectrum(_Model):
    """An inline table of ``wavelengths`` (nm) and ``values``."""

    wavelengths: list[float] = Field(min_length=2)
    values: list[float] = Field(min_length=2)

    @model_validator(mode="after")
    def _same_length(self) -> TableSpectrum:
        if len(self.wavelengths) != len(self.values):
            raise ValueError(f"{len(self.wavelengths)} wavelengths but {len(self.values)} values")
        return self


class ConstantSpectrum(_Model):
    """The same value at every wavelength."""

    value: float = Field(ge=0)


SpectrumSpec = Union[LibrarySpectrum, FileSpectrum, TableSpectrum, ConstantSpectrum]


# ---------------------------------------------------------------------------------------------
# Materials


class _Material(_Model):
    two_sided: bool = True


class Diffuse(_Material):
    kind: Literal["diffuse"]
    reflectance: SpectrumSpec


class RoughPlastic(_Material):
    kind: Literal["roughplastic"]
    reflectance: SpectrumSpec
    alpha: float = Field(default=0.1, gt=0, le=1)
    int_ior: float = Field(default=1.49, gt=1, le=4)
    ext_ior: float = Field(default=1.000277, ge=1, le=4)


class RoughConductor(_Material):
    kind: Literal["roughconductor"]
    conductor: str = "Al"
    alpha: float = Field(default=0.1, gt=0, le=1)
    specular_reflectance: SpectrumSpec | None = None


class Dielectric(_Model):
    kind: Literal["dielectric"]
    int_ior: float = Field(default=1.5046, gt=1, le=4)
    ext_ior: float = Field(default=1.000277, ge=1, le=4)


Material = Annotated[Union[Diffuse, RoughPlastic, RoughConductor, Dielectric], Field(discriminator="kind")]
# Conductor tables built into Mitsuba 3 (its ``roughconductor`` ``material`` parameter).
CONDUCTORS = ("a-C", "Ag", "Al", "AlAs", "AlSb", "Au", "Be", "Cr", "CsI", "Cu", "Cu2O", "CuO", "d-C",
              "Hg", "HgTe", "Ir", "K", "Li", "MgO", "Mo", "Na_palik", "Nb", "Ni_palik", "Rh", "Se",
              "SiC", "SnTe", "Ta", "Te", "ThF4", "TiC", "TiN", "TiO2", "VC", "V_palik", "VN", "W",
              "none")


# ---------------------------------------------------------------------------------------------
# Transforms


class Rotation(_Model):
    axis: Vec3
    angle: float  # degrees

    @field_validator("axis")
    @classmethod
    def _nonzero(cls, v: Vec3) -> Vec3:
        if math.hypot(*v) == 0:
            raise ValueError("rotation axis must not be the zero vector")
        return v


class Transform(_Model):
    """``matrix`` (4×4, row-major) or ``scale`` → ``rotate`` (in list order) → ``translate``."""

    matrix: list[list[float]] | None = None
    scale: float | Vec3 | None = None
    rotate: list[Rotation] = Field(default_factory=list)
    translate: Vec3 | None = None

    @model_validator(mode="after")
    def _check(self) -> Transform:
        if self.matrix is not None:
            if self.scale is not None or self.rotate or self.translate is not None:
                raise ValueError("give either 'matrix' or scale/rotate/translate, not both")
            m = np.asarray(self.matrix, dtype=float)
            if m.shape != (4, 4) or not np.all(np.isfinite(m)):
                raise ValueError("matrix must be 4x4 finite numbers")
            if abs(np.linalg.det(m[:3, :3])) < 1e-12:
                raise ValueError("matrix is singular")
        if self.scale is not None:
            s = np.broadcast_to(np.asarray(self.scale, dtype=float), (3,))
            if np.any(s == 0) or not np.all(np.isfinite(s)):
                raise ValueError("scale must be finite and non-zero")
        return self

    def to_matrix(self) -> np.ndarray:
        """The 4×4 float64 matrix mapping object to world coordinates."""
        if self.matrix is not None:
            return np.asarray(self.matrix, dtype=np.float64)
        m = np.eye(4)
        if self.scale is not None:
            m = np.diag([*np.broadcast_to(np.asarray(self.scale, dtype=float), (3,)), 1.0]) @ m
        for r in self.rotate:
            m = rotation_matrix(r.axis, r.angle) @ m
        if self.translate is not None:
            t = np.eye(4)
            t[:3, 3] = self.translate
            m = t @ m
        return m


def rotation_matrix(axis: Vec3, angle_deg: float) -> np.ndarray:
    """4×4 rotation by ``angle_deg`` degrees about ``axis`` (Rodrigues; right-handed)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    th = math.radians(angle_deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    r = np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)
    m = np.eye(4)
    m[:3, :3] = r
    return m


# ---------------------------------------------------------------------------------------------
# Shapes and emitters


class AreaEmission(_Model):
    """Makes a shape an area light of ``group`` with radiance ``strength`` × the group's spectrum.

    ``portal``: the shape is an emitting *opening*, not geometry — e.g. a window pane standing in for
    the constant sky seen through it (for a uniform sky, a Lambertian emitter of the sky's radiance
    filling the opening gives exactly the light that enters through it, and next-event estimation
    then samples the window instead of the whole sphere). A portal occludes nothing: it is rendered
    in a pass of its own and added (linearity), so it does not block e.g. the sun through the same
    window. A portal has no material, and nothing outside it is seen through it.
    """

    group: Name
    strength: float = Field(gt=0)
    portal: bool = False


class _Shape(_Model):
    name: Name
    material: Name | None = None
    transform: Transform | None = None
    emitter: AreaEmission | None = None

    @model_validator(mode="after")
    def _needs_material_or_emitter(self) -> _Shape:
        if self.material is None and self.emitter is None:
            raise ValueError("a shape needs a 'material', an 'emitter', or both")
        return self


class Rectangle(_Shape):
    type: Literal["rectangle"]


class Cube(_Shape):
    type: Literal["cube"]


class Disk(_Shape):
    type: Literal["disk"]


class Sphere(_Shape):
    type: Literal["sphere"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = Field(default=1.0, gt=0)


class Cylinder(_Shape):
    type: Literal["cylinder"]
    p0: Vec3 = (0.0, 0.0, 0.0)
    p1: Vec3 = (0.0, 0.0, 1.0)
    radius: float = Field(default=1.0, gt=0)

    @model_validator(mode="after")
    def _distinct(self) -> Cylinder:
        if np.allclose(self.p0, self.p1):
            raise ValueError("p0 and p1 must differ")
        return self


class MeshFile(_Shape):
    type: Literal["obj", "ply"]
    filename: str
    face_normals: bool = False


Shape = Annotated[Union[Rectangle, Cube, Disk, Sphere, Cylinder, MeshFile], Field(discriminator="type")]


class _Light(_Model):
    name: Name
    group: Name
    strength: float = Field(gt=0)


class PointLight(_Light):
    type: Literal["point"]
    position: Vec3


class SpotLight(_Light):
    type: Literal["spot"]
    position: Vec3
    target: Vec3
    cutoff_angle: float = Field(default=20.0, gt=0, lt=90)
    beam_width: float | None = Field(default=None, gt=0, lt=90)

    @model_validator(mode="after")
    def _check(self) -> SpotLight:
        if np.allclose(self.position, self.target):
            raise ValueError("position and target must differ")
        if self.beam_width is not None and self.beam_width > self.cutoff_angle:
            raise ValueError("beam_width must not exceed cutoff_angle")
        return self


class DirectionalLight(_Light):
    """A distant light (the sun): ``direction`` is where the light travels *to*."""

    type: Literal["directional"]
    direction: Vec3

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v: Vec3) -> Vec3:
        if math.hypot(*v) == 0:
            raise ValueError("direction must not be the zero vector")
        return v


class ConstantSky(_Light):
    """Uniform radiance from every direction not blocked by geometry."""

    type: Literal["constant"]


class EnvMapSky(_Light):
    """An environment map (lat-long image); its luminance shapes the sky, the group sets the colour."""

    type: Literal["envmap"]
    filename: str
    transform: Transform | None = None


Light = Annotated[Union[PointLight, SpotLight, DirectionalLight, ConstantSky, EnvMapSky],
                  Field(discriminator="type")]


class LightGroup(_Model):
    """A set of emitters that share one illuminant. ``emission`` is the spectrum ``E_g`` the cube is
    rendered with: ``"flat"`` (unit, the default), an illuminant name, or a spectrum."""

    name: Name
    emission: str | TableSpectrum | FileSpectrum = "flat"
    description: str = ""


# ---------------------------------------------------------------------------------------------
# Views


class View(_Model):
    name: Name
    origin: Vec3
    target: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = Field(default=60.0, gt=0, lt=180)  # horizontal, degrees
    resolution: tuple[Annotated[int, Field(ge=1, le=16384)], Annotated[int, Field(ge=1, le=16384)]] = (320, 240)

    @model_validator(mode="after")
    def _check(self) -> View:
        d = np.subtract(self.target, self.origin)
        if np.linalg.norm(d) == 0:
            raise ValueError("origin and target must differ")
        if np.linalg.norm(np.cross(d, self.up)) < 1e-9 * np.linalg.norm(d) * max(np.linalg.norm(self.up), 1e-30):
            raise ValueError("up must not be parallel to the viewing direction")
        return self

    @property
    def width(self) -> int:
        return self.resolution[0]

    @property
    def height(self) -> int:
        return self.resolution[1]


# ---------------------------------------------------------------------------------------------
# Scene


class GridSpec(_Model):
    start: float = 395.0
    end: float = 705.0
    step: float = 5.0


class Scene(_Model):
    """A complete scene: see the module docstring."""

    name: Name
    schema_version: int = SCHEMA_VERSION
    description: str = ""
    grid: GridSpec = GridSpec()
    materials: dict[Name, Material] = Field(default_factory=dict)
    shapes: list[Shape] = Field(default_factory=list)
    lights: list[Light] = Field(default_factory=list)
    light_groups: list[LightGroup] = Field(default_factory=list)
    views: list[View] = Field(min_length=1)
    max_depth: int = Field(default=8, ge=1, le=64)

    _base: Path | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _cross_check(self) -> Scene:
        errors: list[str] = []
        for kind, items in (("shapes", self.shapes), ("lights", self.lights), ("views", self.views),
                            ("light_groups", self.light_groups)):
            seen: set[str] = set()
            for i, it in enumerate(items):
                if it.name in seen:
                    errors.append(f"{kind}[{i}] ({it.name}): name: duplicate name {it.name!r}")
                seen.add(it.name)
        declared = [g.name for g in self.light_groups]
        for i, s in enumerate(self.shapes):
            if s.material is not None and s.material not in self.materials:
                errors.append(f"shapes[{i}] ({s.name}): material: unknown material {s.material!r}; "
                              f"defined: {', '.join(self.materials) or 'none'}")
            if s.emitter is not None and declared and s.emitter.group not in declared:
                errors.append(f"shapes[{i}] ({s.name}): emitter.group: unknown light group "
                              f"{s.emitter.group!r}; declared: {', '.join(declared)}")
            if s.emitter is not None and s.emitter.portal and s.material is not None:
                errors.append(f"shapes[{i}] ({s.name}): material: a portal is not geometry; remove its material")
            if s.emitter is not None and s.material is not None and isinstance(
                    self.materials.get(s.material), Dielectric):
                errors.append(f"shapes[{i}] ({s.name}): emitter: an emitting shape cannot be dielectric")
        for i, light in enumerate(self.lights):
            if declared and light.group not in declared:
                errors.append(f"lights[{i}] ({light.name}): group: unknown light group {light.group!r}; "
                              f"declared: {', '.join(declared)}")
        skies = [light for light in self.lights if light.type in ("constant", "envmap")]
        if len(skies) > 1:
            errors.append(f"lights: at most one sky (constant or envmap) per scene, found "
                          f"{', '.join(s.name for s in skies)}")
        for name, m in self.materials.items():
            if isinstance(m, RoughConductor) and m.conductor not in CONDUCTORS:
                errors.append(f"materials.{name}: conductor: unknown conductor {m.conductor!r}; "
                              f"choose one of {', '.join(CONDUCTORS)}")
        if not self.group_names:
            errors.append("lights: the scene has no emitters; add lights or emitting shapes")
        for g in declared:
            if g not in self._used_groups():
                errors.append(f"light_groups ({g}): group {g!r} has no emitters")
        try:
            SpectralGrid(self.grid.start, self.grid.end, self.grid.step)
        except SpectralError as exc:
            errors.append(f"grid: {exc}")
        if errors:
            raise ValueError(" | ".join(errors))
        return self

    def _used_groups(self) -> list[str]:
        out: list[str] = []
        for s in self.shapes:
            if s.emitter is not None and s.emitter.group not in out:
                out.append(s.emitter.group)
        for light in self.lights:
            if light.group not in out:
                out.append(light.group)
        return out

    # -- derived ---------------------------------------------------------------------------------

    @property
    def spectral_grid(self) -> SpectralGrid:
        return SpectralGrid(self.grid.start, self.grid.end, self.grid.step)

    @property
    def group_names(self) -> list[str]:
        """Light groups in declared order (or in order of first use when none are declared)."""
        if self.light_groups:
            return [g.name for g in self.light_groups]
        return self._used_groups()

    def group(self, name: str) -> LightGroup:
        for g in self.light_groups:
            if g.name == name:
                return g
        if name in self._used_groups():
            return LightGroup(name=name)
        raise SceneError(f"scene {self.name!r}: no light group {name!r}; groups: {', '.join(self.group_names)}")

    def view(self, name: str) -> View:
        for v in self.views:
            if v.name == name:
                return v
        raise SceneError(f"scene {self.name!r}: no view {name!r}; views: {', '.join(v.name for v in self.views)}")

    def is_portal(self, item) -> bool:
        """True for a shape whose area emission is a portal (see :class:`AreaEmission`)."""
        em = getattr(item, "emitter", None)
        return em is not None and em.portal

    def emitters_of(self, group: str) -> list[Shape | Light]:
        """Shapes with area emission and lights of ``group``."""
        return [s for s in self.shapes if s.emitter is not None and s.emitter.group == group] + [
            light for light in self.lights if light.group == group]

    def resolve_path(self, p: str) -> Path:
        path = Path(p).expanduser()
        if not path.is_absolute() and self._base is not None:
            path = self._base / path
        return path

    def with_base(self, base: Path | None) -> Scene:
        self._base = base
        return self

    # -- spectra -------------------------------------------------------------------------------

    def spectrum(self, spec: SpectrumSpec, what: str, *, reflectance: bool = True) -> np.ndarray:
        """Band averages ``(n_bands,)`` float64 of a spectrum spec on the scene grid."""
        from retarget.grid import resample
        from retarget.reflectances import get_reflectances
        from retarget.tables import read_csv_table

        grid = self.spectral_grid
        extend = "constant" if reflectance else "refuse"
        if isinstance(spec, ConstantSpectrum):
            out = np.full(grid.n_bands, float(spec.value))
        elif isinstance(spec, LibrarySpectrum):
            names, r = get_reflectances(spec.library, grid)
            if spec.sample is not None:
                if spec.sample not in names:
                    raise SpectralError(f"{what}: no sample {spec.sample!r} in {spec.library!r}; "
                                        f"samples: {', '.join(names[:30])}")
                out = r[names.index(spec.sample)]
            else:
                if spec.index >= len(names):
                    raise SpectralError(f"{what}: index {spec.index} out of range; {spec.library!r} "
                                        f"has {len(names)} samples (0-based index)")
                out = r[spec.index]
        elif isinstance(spec, FileSpectrum):
            path = self.resolve_path(spec.file)
            wl, v, _ = read_csv_table(str(path), what=f"{what} file {str(path)!r}")
            if spec.column >= v.shape[1]:
                raise SpectralError(f"{what}: column {spec.column} out of range; {path} has "
                                    f"{v.shape[1]} value column(s)")
            out = resample(wl, v[:, spec.column], grid, extend=extend, what=what)
        else:
            out = resample(np.asarray(spec.wavelengths), np.asarray(spec.values), grid, extend=extend,
                           what=what)
        out = np.asarray(out, dtype=np.float64)
        if not np.all(np.isfinite(out)) or np.any(out < 0):
            raise SpectralError(f"{what}: spectrum must be finite and non-negative")
        if reflectance and np.any(out > 1.0 + 1e-6):
            raise SpectralError(f"{what}: reflectance exceeds 1 (max {out.max():.3f}); energy would "
                                "not be conserved")
        return out

    def emission(self, group: str) -> np.ndarray:
        """The emission spectrum ``Ē_g`` ``(n_bands,)`` of a light group (band averages).

        ``"flat"`` is 1 in every band. Illuminant names are looked up in :mod:`retarget.illuminants`
        (photometrically normalised, as everywhere in illumix).
        """
        g = self.group(group)
        grid = self.spectral_grid
        what = f"light_groups ({group}): emission"
        if isinstance(g.emission, str):
            if g.emission == "flat":
                return np.ones(grid.n_bands)
            if g.emission.lower().endswith(".csv"):
                return _library_spd(str(self.resolve_path(g.emission)), grid)
            return _library_spd(g.emission, grid)
        if isinstance(g.emission, FileSpectrum):
            from retarget.tables import read_csv_table

            path = self.resolve_path(g.emission.file)
            wl, v, _ = read_csv_table(str(path), what=f"{what} file {str(path)!r}")
            if g.emission.column >= v.shape[1]:
                raise SpectralError(f"{what}: column {g.emission.column} out of range")
            return spd_from_samples(wl, v[:, g.emission.column], grid, what=what)
        return spd_from_samples(np.asarray(g.emission.wavelengths), np.asarray(g.emission.values),
                                grid, what=what)

    def emission_name(self, group: str) -> str:
        e = self.group(group).emission
        return e if isinstance(e, str) else ("table" if isinstance(e, TableSpectrum) else e.file)

    # -- identity -------------------------------------------------------------------------------

    def content_hash(self) -> str:
        """sha256 over everything that changes the transport cubes except the views: geometry,
        materials, lights, groups, grid, max depth — and the bytes of every referenced file."""
        doc = self.model_dump(mode="json", exclude={"views", "description"})
        files: dict[str, str] = {}
        for p in self.referenced_files():
            path = self.resolve_path(p)
            files[p] = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "missing"
        blob = json.dumps({"scene": doc, "files": files}, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()

    @cached_property
    def scene_hash(self) -> str:
        """:meth:`content_hash`, computed once."""
        return self.content_hash()

    def view_hash(self, view: str) -> str:
        """sha256 of the scene hash and one view's camera (what one cube depends on)."""
        v = self.view(view).model_dump(mode="json")
        return hashlib.sha256(json.dumps([self.scene_hash, v], sort_keys=True).encode()).hexdigest()

    def referenced_files(self) -> list[str]:
        out: list[str] = []
        for s in self.shapes:
            if isinstance(s, MeshFile):
                out.append(s.filename)
        for light in self.lights:
            if isinstance(light, EnvMapSky):
                out.append(light.filename)
        for m in self.materials.values():
            for spec in (getattr(m, "reflectance", None), getattr(m, "specular_reflectance", None)):
                if isinstance(spec, FileSpectrum):
                    out.append(spec.file)
        for g in self.light_groups:
            if isinstance(g.emission, FileSpectrum):
                out.append(g.emission.file)
            elif isinstance(g.emission, str) and g.emission.lower().endswith(".csv"):
                out.append(g.emission)
        return out

    def check_resources(self) -> None:
        """Resolve every spectrum and file now, so a bad scene fails before anything renders."""
        errors: list[str] = []
        for p in self.referenced_files():
            if not self.resolve_path(p).is_file():
                errors.append(f"file {p!r} does not exist (resolved to {str(self.resolve_path(p))!r})")
        for name, m in self.materials.items():
            for field in ("reflectance", "specular_reflectance"):
                spec = getattr(m, field, None)
                if spec is not None:
                    try:
                        self.spectrum(spec, f"materials.{name}.{field}")
                    except (SpectralError, OSError) as exc:
                        errors.append(str(exc))
        for g in self.group_names:
            try:
                e = self.emission(g)
                if not np.any(e > 0):
                    errors.append(f"light_groups ({g}): emission is zero in every band")
            except (SpectralError, OSError) as exc:
                errors.append(str(exc))
        if errors:
            raise SceneError(" | ".join(errors))


# ---------------------------------------------------------------------------------------------
# Loading


def _format_loc(doc: Any, loc: tuple) -> str:
    """``shapes[3] (ball).radius`` from a pydantic error location, naming objects by their name."""
    parts: list[str] = []
    node = doc
    for key in loc:
        if isinstance(key, int):
            name = node[key].get("name") if isinstance(node, list) and key < len(node) and isinstance(
                node[key], dict) else None
            parts[-1:] = [f"{parts[-1] if parts else ''}[{key}]" + (f" ({name})" if name else "")]
            node = node[key] if isinstance(node, list) and key < len(node) else None
        else:
            if isinstance(node, dict) and key in node:
                node = node[key]
            elif isinstance(node, dict):
                # Tagged-union branch names (e.g. 'rectangle', 'diffuse') are not document keys.
                if key in ("rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "point",
                           "spot", "directional", "constant", "envmap", "diffuse", "roughplastic",
                           "roughconductor", "dielectric") or key.endswith("Spectrum") or key in (
                               "str", "list[float]", "float", "tuple[float, float, float]"):
                    continue
                node = None
            else:
                node = None
            parts.append(str(key))
    return ".".join(parts) if parts else "(top level)"


def _format_errors(doc: Any, exc: ValidationError, source: str) -> str:
    msgs = []
    for err in exc.errors():
        loc = _format_loc(doc, tuple(err["loc"]))
        msg = err["msg"].removeprefix("Value error, ")
        if err.get("type") in ("union_tag_invalid", "union_tag_not_found"):
            tag = str((err.get("ctx") or {}).get("discriminator", "")).strip("'")
            loc = f"{loc}.{tag}" if loc != "(top level)" else tag
        msgs.append(f"{loc}: {msg}" if loc != "(top level)" else msg)
    # Union branches repeat the same location; keep each message once.
    unique = list(dict.fromkeys(msgs))
    return f"{source}: " + "; ".join(unique[:8]) + (f"; … {len(unique) - 8} more" if len(unique) > 8 else "")


def scene_from_dict(doc: Any, *, source: str = "scene", base: Path | None = None,
                    check: bool = True) -> Scene:
    """Validate a parsed document (one scene) into a :class:`Scene`; :class:`SceneError` if bad."""
    if not isinstance(doc, dict):
        raise SceneError(f"{source}: a scene must be a mapping, got {type(doc).__name__}")
    try:
        scene = Scene.model_validate(doc)
    except ValidationError as exc:
        raise SceneError(_format_errors(doc, exc, source)) from None
    scene = scene.with_base(base)
    if check:
        try:
            scene.check_resources()
        except SceneError as exc:
            raise SceneError(f"{source}: scene {scene.name!r}: {exc}") from None
    return scene


def load_scenes(path: str | Path, *, check: bool = True) -> list[Scene]:
    """Load a YAML or JSON file holding one scene or ``{scenes: [...]}``."""
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"scene file {str(p)!r} does not exist")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{p}: cannot read ({exc})") from None
    try:
        doc = json.loads(text) if p.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()
        raise SceneError(f"{p}: not valid {'JSON' if p.suffix.lower() == '.json' else 'YAML'}: "
                         f"{' '.join(s.strip() for s in first)}") from None
    docs = doc["scenes"] if isinstance(doc, dict) and "scenes" in doc and len(doc) == 1 else [doc]
    if not isinstance(docs, list) or not docs:
        raise SceneError(f"{p}: 'scenes' must be a non-empty list")
    scenes = [scene_from_dict(d, source=f"{p}" + (f" scenes[{i}]" if len(docs) > 1 else ""),
                              base=p.parent.resolve(), check=check) for i, d in enumerate(docs)]
    names = [s.name for s in scenes]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"{p}: duplicate scene names {sorted(dup)}")
    return scenes


def dump_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene as YAML (``.yaml``/``.yml``) or JSON."""
    p = Path(path)
    doc = scene.model_dump(mode="json", exclude_defaults=False)
    if p.suffix.lower() == ".json":
        p.write_text(json.dumps(doc, indent=1))
    else:
        p.write_text(yaml.safe_dump(doc, sort_keys=False))
