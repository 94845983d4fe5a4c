"""Scene description, part 1: the pieces of a scene — spectra, materials, transforms, shapes,
lights, light groups and views — as strict pydantic v2 models.

The whole scene (:class:`scene.model.Scene`) is assembled from these and loaded from
YAML/JSON by :mod:`scene.load`. This is the renderer-independent description: the
Mitsuba backend (:mod:`renderer_jobs.mitsuba.scene_dict`) turns it into a Mitsuba scene; nothing here
imports Mitsuba.

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
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from illumix.scene.spectra import (NAME_PATTERN, SCHEMA_VERSION, ConstantSpectrum, FileSpectrum,  # noqa: F401
                                         LibrarySpectrum, Name, SceneError, SpectrumSpec, StrictModel,
                                         TableSpectrum, Vec3)
from illumix.scene.textures import BitmapTexture, NormalMap, PatternTexture, Reflectance  # noqa: F401


# ---------------------------------------------------------------------------------------------
# Materials


class _Material(StrictModel):
    two_sided: bool = True
    normal_map: NormalMap | None = None  # bends the shading normal (textures.NormalMap); needs the shape's UVs


class Diffuse(_Material):
    kind: Literal["diffuse"]
    reflectance: Reflectance


class RoughPlastic(_Material):
    kind: Literal["roughplastic"]
    reflectance: Reflectance
    alpha: float = Field(default=0.1, gt=0, le=1)
    int_ior: float = Field(default=1.49, gt=1, le=4)
    ext_ior: float = Field(default=1.000277, ge=1, le=4)


class RoughConductor(_Material):
    kind: Literal["roughconductor"]
    conductor: str = "Al"
    alpha: float = Field(default=0.1, gt=0, le=1)
    specular_reflectance: SpectrumSpec | None = None


class Dielectric(StrictModel):
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


class Rotation(StrictModel):
    axis: Vec3
    angle: float  # degrees

    @field_validator("axis")
    @classmethod
    def _nonzero(cls, v: Vec3) -> Vec3:
        if math.hypot(*v) == 0:
            raise ValueError("rotation axis must not be the zero vector")
        return v


class Transform(StrictModel):
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


class AreaEmission(StrictModel):
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


def _renderer_key(v: str) -> str:
    # shape and light names become Mitsuba object keys, where '.' separates an object path
    if "." in v:
        raise ValueError(f"name {v!r} contains '.', which the renderer reserves (Mitsuba object paths); "
                         f"use e.g. {v.replace('.', '_')!r}")
    return v


class _Shape(StrictModel):
    name: Name
    material: Name | None = None
    transform: Transform | None = None
    emitter: AreaEmission | None = None

    _key = field_validator("name")(_renderer_key)

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

    @model_validator(mode="after")
    def _similarity_only(self) -> Sphere:
        # Mitsuba's sphere stays round under any transform (it takes the radius from one axis and
        # only warns), so a non-uniform scale or shear would render something other than described.
        if self.transform is not None:
            a = self.transform.to_matrix()[:3, :3]
            g = a.T @ a
            if not np.allclose(g, g[0, 0] * np.eye(3), rtol=1e-6, atol=1e-12 * abs(g[0, 0])):
                raise ValueError("a sphere's transform must scale uniformly (rotation, translation and one "
                                 "scale factor); for an ellipsoid use a mesh (type: obj or ply)")
        return self


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


class _Light(StrictModel):
    name: Name
    group: Name
    strength: float = Field(gt=0)

    _key = field_validator("name")(_renderer_key)


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


class LightGroup(StrictModel):
    """A set of emitters that share one illuminant. ``emission`` is the spectrum ``E_g`` the cube is
    rendered with: ``"flat"`` (unit, the default), an illuminant name, or a spectrum. ``kind``:
    ``daylight`` (sun, sky, windows) or ``artificial`` (lamps); when omitted the scene infers it from
    the group's emitters (:meth:`scene.model.Scene.group_kind`). ``pair=`` lights daylight groups
    with the pair's daylight illuminant and artificial ones with the other. It does not change the
    cubes (not part of the scene hash)."""

    name: Name
    emission: str | TableSpectrum | FileSpectrum = "flat"
    description: str = ""
    kind: Literal["daylight", "artificial"] | None = None


# ---------------------------------------------------------------------------------------------
# Views


class View(StrictModel):
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
