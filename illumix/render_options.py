"""Render options → :class:`~renderer_jobs.render_settings.RenderSettings`, checked once for every
command that renders (``illumix render`` from its flags, ``illumix dataset`` from a config's
``render`` section). ``flag(name)`` spells an option the way the user wrote it (``--noise-target``
on the command line, ``render.noise_target`` in a config), so each error names what to change.

Imports nothing heavy at module level (``--help`` stays cheap).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from illumix.errors import UserError


def cli_flag(name: str) -> str:
    """``noise-target`` → ``--noise-target``."""
    return f"--{name}"


def check_executor(executor: str, address: str | None, flag: Callable[[str], str] = cli_flag) -> str:
    """The canonical executor name; an address is only for Ray."""
    from illumix.renderer_jobs.modes import EXECUTORS
    from illumix.retarget.errors import UnknownName

    try:
        executor = EXECUTORS.canonical(executor)
    except UnknownName as exc:
        raise UserError(f"{flag('executor')}: {exc}") from None
    if executor == "local" and address:
        raise UserError(f"{flag('address')} is for {flag('executor')} ray")
    return executor


def render_settings(*, spp: int, seed: int, wavelengths: str, sampler: str, bands_per_path: int,
                    skip_dark: bool, adaptive: bool, noise_target: float | None, illumination: bool,
                    denoise: str | None, backend: str, scenes: Iterable = (),
                    flag: Callable[[str], str] = cli_flag, boost_factor: int | None = None,
                    boost_reach: float | None = None):
    """The :class:`RenderSettings` of these options, after the checks that need the scenes (a
    stratified render needs ``4 * spp`` ≥ the bands). A noise target implies adaptive spp.
    Raises :class:`UserError` (or :class:`~renderer_jobs.scene_schema.SceneError` from the settings'
    own checks, which the caller reports as one line)."""
    from illumix.renderer_jobs.mitsuba_render import RenderSettings

    for s in scenes:
        if 4 * spp < s.spectral_grid.n_bands and wavelengths == "stratified" and backend == "mitsuba":
            raise UserError(f"{flag('spp')} {spp} is too low: stratified sampling of {s.spectral_grid.n_bands} "
                            f"bands needs spp >= {-(-s.spectral_grid.n_bands // 4)}")
    if noise_target is not None and not 0 < noise_target < 1:
        raise UserError(f"{flag('noise-target')} {noise_target} must lie in (0, 1): a relative standard deviation, "
                        "e.g. 0.05 for 5 %")
    adaptive = adaptive or noise_target is not None  # a target spreads paths by the adaptive pilot
    settings = RenderSettings(spp=spp, seed=seed, wavelengths=wavelengths, sampler=sampler,
                              bands_per_path=bands_per_path, skip_dark=skip_dark,
                              adaptive=adaptive, noise_target=noise_target, illumination=illumination,
                              denoise=denoise, backend=backend, boost_factor=boost_factor,
                              **({} if boost_reach is None else {"boost_reach": boost_reach}))
    if boost_reach is not None and settings.boost_factor == 1:
        raise UserError(f"{flag('boost-reach')} chooses where the targeted extra paths go, but there are none "
                        f"here ({flag('boost-factor')} 1, or not all-bands with denoise dt-irradiance); drop it")
    return settings
