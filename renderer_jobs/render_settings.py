"""How a cube is rendered: :class:`RenderSettings`, checked when made (one error naming the fix).

Pure settings, no Mitsuba: the command line and the job runner build them; the renderers
(:mod:`renderer_jobs.mitsuba_render`, :mod:`renderer_jobs.cycles_render`) read them.
"""

from __future__ import annotations

from dataclasses import dataclass

from illumix.renderer_jobs.modes import SAMPLERS, WAVELENGTH_MODES
from illumix.renderer_jobs.scene_schema import SceneError
from illumix.retarget.denoise_methods import DEFAULT_METHOD

DEFAULT_BOOST_FACTOR = 8  # bench/DENOISE.md: 8x the spp where reach > 0.6 brings front's p99.3 under 2.5 %
DEFAULT_BANDS = 63  # the default grid's bands (395–705 nm): the spp checks assume a group emitting in all


@dataclass(frozen=True)
class RenderSettings:
    """spp: paths per pixel; seed: RNG seed of the cube; wavelengths: ``"all-bands"`` (every path
    carries every band, rendered by Mitsuba's loop with ``sampler``: :mod:`renderer_jobs.mitsuba_band_render`),
    ``"stratified"`` or ``"random"`` (4 wavelengths per path, numpy-driven: :mod:`renderer_jobs.mitsuba_render`);
    sampler: Mitsuba's pixel sampler for ``"all-bands"`` (:data:`renderer_jobs.modes.SAMPLERS`; its spp
    rules apply to each band set's share of spp); bands_per_path (``"all-bands"``): the most bands
    one path carries (a multiple of 4); the live bands render in interleaved sets of at most this
    many that share the pixel's ``spp`` paths equally (4 sets of 16 for 63 bands at the default: each
    band averages spp/4 paths); max_lanes (4-wavelength modes): paths traced per pass (bounds memory; all-bands renders run in Mitsuba's
    own loop, whose memory is the film's); aov_spp: samples per pixel of the
    AOV pass; resolution: ``(width, height)`` overriding the view's; adaptive (hero wavelength modes
    only): spread the spp budget over the pixels by a pilot's variance (:mod:`renderer_jobs.adaptive_spp`;
    spp ≥ 2 × pilot, else uniform); skip_background (hero modes): trace no paths in pixels that cannot
    see geometry when the groups have no sky (they are exactly zero; :mod:`renderer_jobs.view_coverage`;
    in ``"all-bands"`` such a path ends at its first missed ray, exactly zero too); noise_target (hero
    modes): instead of a fixed budget, give each pixel the paths its pilot predicts for this relative
    noise of its spectral sum (e.g. 0.05), ``spp`` then being the per-pixel maximum
    (:func:`renderer_jobs.adaptive_spp.to_target`); illumination: also render the illumination cube
    (:mod:`renderer_jobs.mitsuba_render`, "Illumination cube"); denoise: the :mod:`retarget.denoise` method whose
    denoised copies the job runner stores beside each cube (``None``/``"none"``: no copies);
    backend: ``"mitsuba"`` or ``"cycles"`` (:mod:`renderer_jobs.cycles_render`, which uses spp, seed,
    resolution, aov_spp and illumination, and renders every group of a view at once).
    For the job runner (:mod:`renderer_jobs.jobs`) only: skip_dark: probe each (view, group) first
    and record a group that sends no light into the view as empty instead of rendering it
    (:mod:`renderer_jobs.light_probe`); probe_ratio: the probe's budget is 1/probe_ratio of the
    cube's paths; boost_factor (``"all-bands"`` with ``denoise`` ``dt-irradiance``): pixels the
    denoiser cannot average (reach > boost_reach, :mod:`renderer_jobs.boost_paths`, from the guides
    alone) get this many times ``spp`` (1: off; ``None``: 8 where it applies, else 1)."""

    spp: int = 64
    seed: int = 0
    wavelengths: str = "all-bands"
    sampler: str = "multijitter"
    bands_per_path: int = 16
    max_lanes: int = 1 << 20
    aov_spp: int = 16  # the denoising guides: bench/denoise.py measures them at 16 rays per pixel
    resolution: tuple[int, int] | None = None
    skip_dark: bool = True
    probe_ratio: int = 16
    adaptive: bool = False
    skip_background: bool = True
    noise_target: float | None = None
    illumination: bool = True
    denoise: str | None = DEFAULT_METHOD
    backend: str = "mitsuba"
    boost_factor: int | None = None
    boost_reach: float = 0.6

    def __post_init__(self) -> None:
        from illumix.renderer_jobs.modes import BACKENDS  # noqa: PLC0415
        from illumix.retarget.errors import UnknownName  # noqa: PLC0415

        try:
            object.__setattr__(self, "backend", BACKENDS.canonical(self.backend))
        except UnknownName as exc:
            raise SceneError(str(exc)) from None
        if self.spp < 1:
            raise SceneError(f"spp must be >= 1, got {self.spp}")
        if self.wavelengths not in WAVELENGTH_MODES:
            raise SceneError(str(WAVELENGTH_MODES.unknown(self.wavelengths)))
        # Any accepted spelling ("Stratified") becomes the canonical name the renderer compares with.
        object.__setattr__(self, "wavelengths", WAVELENGTH_MODES.canonical(self.wavelengths))
        if self.sampler not in SAMPLERS:
            raise SceneError(str(SAMPLERS.unknown(self.sampler)))
        object.__setattr__(self, "sampler", SAMPLERS.canonical(self.sampler))
        if self.wavelengths == "all-bands" and self.backend == "mitsuba":
            from illumix.renderer_jobs.mitsuba_band_render import check_spp  # noqa: PLC0415

            if self.bands_per_path < 4 or self.bands_per_path % 4:
                raise SceneError(f"bands per path {self.bands_per_path} must be a positive multiple of 4 "
                                 "(Mitsuba traces wavelengths in fours)")
            check_spp(self.sampler, self.spp, self.bands_per_path, DEFAULT_BANDS)
            if self.adaptive or self.noise_target is not None:
                raise SceneError("adaptive spp and noise targets spread paths by a pilot of 4-wavelength paths: "
                                 "they need wavelengths 'stratified' (all-bands paths are uniform per pixel)")
        if self.max_lanes < 1:
            raise SceneError("max_lanes must be >= 1")
        if self.denoise is not None:
            from illumix.retarget.denoise import DENOISE_METHODS  # noqa: PLC0415
            from illumix.retarget.errors import UnknownName  # noqa: PLC0415

            try:
                name = None if str(self.denoise).lower() == "none" else DENOISE_METHODS.canonical(self.denoise)
            except UnknownName as exc:
                raise SceneError(f"{exc} (or none)") from None
            object.__setattr__(self, "denoise", name)
        self._check_boost()
        if self.probe_ratio < 1:
            raise SceneError("probe_ratio must be >= 1")
        if self.noise_target is not None and not 0 < self.noise_target < 1:
            raise SceneError(f"noise target {self.noise_target} must lie in (0, 1): a relative standard "
                             "deviation, e.g. 0.05 for 5 %")

    def _check_boost(self) -> None:
        applies = self.backend == "mitsuba" and self.wavelengths == "all-bands" and self.denoise == "dt-irradiance"
        if self.boost_factor is None:
            object.__setattr__(self, "boost_factor", DEFAULT_BOOST_FACTOR if applies else 1)
        if isinstance(self.boost_factor, bool) or int(self.boost_factor) != self.boost_factor or self.boost_factor < 1:
            raise SceneError(f"boost factor {self.boost_factor!r} must be a whole number >= 1 (1: no extra paths)")
        object.__setattr__(self, "boost_factor", int(self.boost_factor))
        if not 0 < self.boost_reach <= 1:
            raise SceneError(f"boost reach {self.boost_reach} must lie in (0, 1]: the share of white noise the "
                             "denoiser leaves in a pixel (default 0.6)")
        if self.boost_factor > 1 and not applies:
            raise SceneError("a boost factor > 1 needs the mitsuba backend, wavelengths 'all-bands' and denoise "
                             "'dt-irradiance' (the extra paths go where that filter cannot reach): use --boost-factor 1 "
                             "(render.boost_factor: 1 in a dataset config)")

    def to_dict(self) -> dict:
        return {"spp": self.spp, "seed": self.seed, "wavelengths": self.wavelengths, "sampler": self.sampler,
                "bands_per_path": self.bands_per_path,
                "max_lanes": self.max_lanes, "aov_spp": self.aov_spp,
                "resolution": list(self.resolution) if self.resolution else None,
                "skip_dark": self.skip_dark, "probe_ratio": self.probe_ratio, "adaptive": self.adaptive,
                "skip_background": self.skip_background, "noise_target": self.noise_target,
                "illumination": self.illumination, "denoise": self.denoise, "backend": self.backend,
                "boost_factor": self.boost_factor, "boost_reach": self.boost_reach}
