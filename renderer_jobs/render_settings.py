"""How a cube is rendered: one pydantic :class:`RenderSettings`, checked when made (one error naming the fix).

The single description of every render option: a field's ``description`` is ``illumix render``'s
``--help`` text for it and its range the option's (:mod:`illumix.render_options` builds the
command-line options from the fields marked ``cli``); a dataset config's ``render:`` section is
these fields (plus where the jobs run); the job runner carries ``model_dump()`` between processes.
Pure settings, no Mitsuba: the renderers (:mod:`renderer_jobs.mitsuba.render`,
:mod:`renderer_jobs.cycles.render`) read them.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictInt, ValidationError, model_validator

from illumix.renderer_jobs import modes
from illumix.scene.spectra import SceneError  # (scene_schema imports numpy)
from illumix.retarget.denoise_methods import DEFAULT_METHOD
from illumix.retarget.errors import UnknownName

DEFAULT_BOOST_FACTOR = 8  # bench/DENOISE.md: 8x the spp where reach > 0.6 brings front's p99.3 under 2.5 %
GENERATED_CLEAN_MAX_SPP = 1024  # bench/SCENES.md: 27 of 28 held-out generated cubes clean by it, 3.2x the CPU
DEFAULT_BANDS = 63  # the default grid's bands (395–705 nm): the spp checks assume a group emitting in all
CLI = {"cli": True}  # a field offered as an `illumix render` option (--name, or --name/--no-name)
# json_schema_extra keys: "note" (more help text), "cli_unset" (the option's default is unset: None)


def generated_room(scene) -> bool:
    """Whether ``scene`` was made by the room generator (its ``generator`` names illumix.scenegen)."""
    return (getattr(scene, "generator", None) or {}).get("name") == "illumix.scenegen"


class RenderSettings(BaseModel):
    """Every option of a render (field descriptions). Frozen; any accepted spelling of a registry
    name (``"Stratified"``, ``"blender"``) becomes its canonical name; an invalid combination raises
    :class:`~scene.schema.SceneError` with one line naming the fix."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    spp: int = Field(64, ge=1, json_schema_extra=CLI, description=(
        "Paths per pixel (all-bands: shared by the band sets, each path carrying up to --bands-per-path bands, a "
        "multiple of the sets: 4 for 63 bands at 16; stratified/random: 4 wavelengths each, >= 16 on 63 bands)."))
    seed: int = Field(0, ge=0, le=2**32 - 1, json_schema_extra=CLI, description=(
        "Render seed (same seed, same cube; each light group's paths mix in the group's name)."))
    wavelengths: str = Field("all-bands", json_schema_extra=CLI, description="Wavelength sampling")
    sampler: str = Field("multijitter", json_schema_extra=CLI, description="Pixel sampler of the all-bands mode")
    bands_per_path: int = Field(16, ge=4, json_schema_extra=CLI, description=(
        "All-bands mode: the most bands one path carries (a multiple of 4); the bands render in interleaved sets "
        "of this many sharing --spp (bench/RENDER_PERF.md: fewer = cheaper paths, lower raw noise per second; "
        "more = lower band noise per second)."))
    max_lanes: int = Field(1 << 20, ge=1, description=(
        "4-wavelength modes: paths traced per pass (bounds memory; all-bands renders run in Mitsuba's own loop)."))
    aov_spp: int = Field(16, ge=1, description="Samples per pixel of the AOV pass (the denoising guides).")
    resolution: tuple[int, int] | None = Field(None, description="(width, height) overriding the views'.")
    skip_dark: bool = Field(True, json_schema_extra=CLI, description=(
        "Probe each view/group first (<= 1/16 of its paths) and record a group that sends no light into the view "
        "as empty instead of rendering it."))
    probe_ratio: int = Field(16, ge=1, description="The dark-group probe's budget: 1/probe_ratio of the cube's paths.")
    adaptive: bool = Field(False, json_schema_extra=CLI, description=(
        "With --wavelengths stratified: spread the spp budget over the pixels by a 16-spp pilot's variance (same "
        "total paths); default: the same spp in every pixel (bench/RENDER_PERF.md measures both)."))
    skip_background: bool = Field(True, description=(
        "Hero modes: trace no paths in pixels that cannot see geometry when the groups have no sky."))
    noise_target: float | None = Field(None, json_schema_extra=CLI, description=(
        "With --wavelengths stratified: render each pixel to this relative noise of its spectral sum as the pilot "
        "predicts it (e.g. 0.05 = 5 %); --spp becomes the per-pixel maximum."))
    clean_max_spp: int | None = Field(None, ge=0, json_schema_extra=CLI, description=(
        "All-bands: while a cube's two independent halves (its even and odd band sets) disagree as a noisy cube "
        "does (bench/SCENES.md), give it as many paths again, up to this many per pixel in all (e.g. 1024); "
        "0: exactly --spp; default: 1024 for generated rooms (illumix.scenegen), 0 for other scenes."))
    guide_paths: bool = Field(True, json_schema_extra=CLI, description=(
        "With the until-clean rule: its rounds from the third on learn where light comes from (a short training "
        "render) and take half their bounces from that path guide (unbiased: MIS with the BSDF); --no-guide-paths: plain "
        "paths only (bench/SCENES.md, \"Path guiding\")."))
    light_paths: bool = Field(True, json_schema_extra=CLI, description=(
        "With the until-clean rule (a cube of one group): half its third round's paths are traced from the lights "
        "to the camera, and each later round takes whichever kind of path (plain, guided, light) has given the least "
        "noise per CPU second; light paths find light that arrives by bounces (a lamp lighting the ceiling, a lamp "
        "next door, the sun's patch on a floor lighting the next room: a sun's paths start in the windows). "
        "Unbiased: every kind estimates the same cube. --no-light-paths: camera paths only "
        "(bench/SCENES.md, \"Light paths\")."))
    illumination: bool = Field(True, json_schema_extra=CLI, description=(
        "Also render each cube's illumination cube (what a white surface would show, bounce light included): the "
        "physical ground truth the service serves; --no-illumination: transport only (the formula ground truth)."))
    denoise: str | None = Field(DEFAULT_METHOD, json_schema_extra=CLI, description=(
        "Also store a denoised copy of every cube and illumination cube, made with this guide-only linear filter "
        "(relighting stays exact); the raw cubes stay, /sample?denoise= picks"))
    backend: str = Field("mitsuba", description="Renderer", json_schema_extra={"cli": True, "note": (
        " Cycles needs Blender: bash scripts/install.sh --blender; it uses --spp (per pass), --seed, --resolution, "
        "--illumination and --denoise, and renders every group of a view at once.")})
    boost_factor: StrictInt | None = Field(None, json_schema_extra=CLI, description=(
        "Targeted extra paths: pixels the dt-irradiance denoiser cannot average (see --boost-reach) get this many "
        "times --spp; 1 = off; default 8 with --denoise dt-irradiance and all-bands, else 1 (bench/DENOISE.md)."))
    # its option is unset by default: given with no extra paths to place, it is refused (render_options)
    boost_reach: float = Field(0.6, json_schema_extra={"cli": True, "cli_unset": True}, description=(
        "Boost pixels where the denoiser keeps more than this share of white noise, (0, 1] (default 0.6), computed "
        "from the guides alone before rendering."))

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:  # one line naming the field, as every settings error
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first.get("loc", ()))
            msg = str(first.get("msg", "invalid")).removeprefix("Value error, ")
            raise SceneError(msg if not where or msg.startswith(where) else f"{where}: {msg}") from None

    @model_validator(mode="before")
    @classmethod
    def _canonical(cls, data: Any) -> Any:
        """Registry spellings → canonical names; the boost factor's default, which depends on them."""
        if not isinstance(data, dict):
            return data
        d = dict(data)
        for key, registry in (("backend", modes.BACKENDS), ("wavelengths", modes.WAVELENGTH_MODES),
                              ("sampler", modes.SAMPLERS)):
            if key in d and d[key] is not None:
                try:
                    d[key] = registry.canonical(str(d[key]))
                except UnknownName as exc:
                    raise SceneError(str(exc)) from None
        d["denoise"] = _denoise_method(d.get("denoise", DEFAULT_METHOD))
        if d.get("boost_factor") is None:
            applies = (d.get("backend", "mitsuba") == "mitsuba" and d.get("wavelengths", "all-bands") == "all-bands"
                       and d["denoise"] == "dt-irradiance")
            d["boost_factor"] = DEFAULT_BOOST_FACTOR if applies else 1
        bf = d["boost_factor"]
        if isinstance(bf, bool) or not isinstance(bf, (int, float)) or int(bf) != bf or bf < 1:
            raise SceneError(f"boost factor {bf!r} must be a whole number >= 1 (1: no extra paths)")
        d["boost_factor"] = int(bf)
        if "resolution" in d and d["resolution"] is not None:
            d["resolution"] = tuple(d["resolution"])  # a list after a JSON round trip
        return d

    @model_validator(mode="after")
    def _consistent(self) -> RenderSettings:
        if self.wavelengths == "all-bands" and self.backend == "mitsuba":
            from illumix.renderer_jobs.mitsuba.band_render import check_spp  # noqa: PLC0415

            if self.bands_per_path % 4:
                raise SceneError(f"bands per path {self.bands_per_path} must be a positive multiple of 4 "
                                 "(Mitsuba traces wavelengths in fours)")
            check_spp(self.sampler, self.spp, self.bands_per_path, DEFAULT_BANDS)
            if self.clean_max_spp:
                if self.clean_max_spp < self.spp:
                    raise SceneError(f"clean max spp {self.clean_max_spp} is below --spp {self.spp}: the cube starts "
                                     "at --spp and only adds paths: use a cap >= --spp, or 0 for exactly --spp")
                check_spp(self.sampler, self.spp // 2, self.bands_per_path, DEFAULT_BANDS)  # its halves
            if self.adaptive or self.noise_target is not None:
                raise SceneError("adaptive spp and noise targets spread paths by a pilot of 4-wavelength paths: "
                                 "they need wavelengths 'stratified' (all-bands paths are uniform per pixel)")
        if self.clean_max_spp and not (self.wavelengths == "all-bands" and self.backend == "mitsuba"):
            raise SceneError("--clean-max-spp renders all-bands cubes in rounds: it needs the mitsuba backend and "
                             "wavelengths 'all-bands'")
        if self.noise_target is not None and not 0 < self.noise_target < 1:
            raise SceneError(f"noise target {self.noise_target} must lie in (0, 1): a relative standard "
                             "deviation, e.g. 0.05 for 5 %")
        if not 0 < self.boost_reach <= 1:
            raise SceneError(f"boost reach {self.boost_reach} must lie in (0, 1]: the share of white noise the "
                             "denoiser leaves in a pixel (default 0.6)")
        applies = self.backend == "mitsuba" and self.wavelengths == "all-bands" and self.denoise == "dt-irradiance"
        if self.boost_factor > 1 and not applies:
            raise SceneError("a boost factor > 1 needs the mitsuba backend, wavelengths 'all-bands' and denoise "
                             "'dt-irradiance' (the extra paths go where that filter cannot reach): use --boost-factor 1 "
                             "(render.boost_factor: 1 in a dataset config)")
        return self

    def clean_cap(self, scene) -> int:
        """The until-clean cap this render applies to ``scene`` (0: none): ``clean_max_spp`` when
        given; unset, :data:`GENERATED_CLEAN_MAX_SPP` for a generated room (``scene.generator`` names
        illumix.scenegen) rendered all-bands on Mitsuba at an spp whose halves the sampler takes,
        else 0 — so that generated rooms come out clean at the default settings wherever paths can
        make them so (issue 39, bench/SCENES.md)."""
        if self.clean_max_spp is not None:
            return self.clean_max_spp
        if not generated_room(scene) or self.backend != "mitsuba" or self.wavelengths != "all-bands":
            return 0
        from illumix.renderer_jobs.mitsuba.band_render import check_spp  # noqa: PLC0415

        try:  # halves the sampler cannot split into band sets: exactly --spp
            check_spp(self.sampler, self.spp // 2, self.bands_per_path, DEFAULT_BANDS)
        except SceneError:
            return 0
        return max(GENERATED_CLEAN_MAX_SPP, self.spp)

    def to_dict(self) -> dict:
        """What a job carries between processes (JSON-able; ``RenderSettings(**d)`` gives it back)."""
        return self.model_dump(mode="json")

    @classmethod
    def cli_fields(cls) -> list[str]:
        """The fields offered as ``illumix render`` options, in declaration order."""
        return [n for n, f in cls.model_fields.items() if (f.json_schema_extra or {}).get("cli")]


def _denoise_method(value: Any) -> str | None:
    """The canonical denoise method, or None for none."""
    if value is None or str(value).lower() == "none":
        return None
    from illumix.retarget.denoise import DENOISE_METHODS  # noqa: PLC0415 - numpy; only when denoising

    try:
        return DENOISE_METHODS.canonical(str(value))
    except UnknownName as exc:
        raise SceneError(f"{exc} (or none)") from None
