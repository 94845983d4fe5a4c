"""Render options → :class:`~renderer_jobs.render_settings.RenderSettings`, checked once for every
command that renders (``illumix render`` from its flags, ``illumix dataset`` from a config's
``render`` section). ``flag(name)`` spells an option the way the user wrote it (``--noise-target``
on the command line, ``render.noise_target`` in a config), so each error names what to change.

Imports nothing heavy at module level (``--help`` stays cheap).
"""

from __future__ import annotations

import functools
import inspect
import typing
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


#: Fields whose options take one name of a registry (choices in --help, any spelling accepted).
def _registries() -> dict:
    from illumix.renderer_jobs.modes import BACKENDS, SAMPLERS, WAVELENGTH_MODES
    from illumix.retarget.denoise_methods import DENOISE_CHOICES

    return {"wavelengths": WAVELENGTH_MODES, "sampler": SAMPLERS, "denoise": DENOISE_CHOICES, "backend": BACKENDS}


def settings_parameters() -> list[inspect.Parameter]:
    """``illumix render``'s render options, one per :class:`RenderSettings` field marked ``cli``: the
    field's description is the help, its default and range the option's (``--name`` for
    ``name``, ``--name/--no-name`` for a flag, the registry's choices for a named method)."""
    import typer

    from illumix.options import SEED_MAX, choice_option, described
    from illumix.renderer_jobs.render_settings import RenderSettings

    registries = _registries()
    out = []
    for name in RenderSettings.cli_fields():
        f = RenderSettings.model_fields[name]
        flag = cli_flag(name.replace("_", "-"))
        extra = f.json_schema_extra or {}
        help_ = f.description + extra.get("note", "")
        default = None if extra.get("cli_unset") else f.default
        if name in registries:
            option = choice_option(registries[name], flag, f"{f.description} — {described(registries[name])}."
                                   + extra.get("note", ""), default=f.default)
            annotation = str
        elif f.annotation is bool:
            option, annotation = typer.Option(f.default, f"{flag}/--no-{name.replace('_', '-')}", help=help_), bool
        else:
            bounds = {m.__class__.__name__: m for m in f.metadata}
            kind = int if "int" in str(f.annotation).lower() else float
            limits = {}
            if "Ge" in bounds:
                limits["min"] = bounds["Ge"].ge
            if name == "seed":
                limits["max"] = SEED_MAX
            option = typer.Option(default, flag, help=help_, **limits)
            annotation = kind | None if default is None else kind
        out.append(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=option, annotation=annotation))
    return out


def with_settings_options(fn: Callable) -> Callable:
    """A command whose parameter ``settings_options`` stands for :func:`settings_parameters`: typer
    sees each option; the command gets them as one dict (field → value)."""
    sig = inspect.signature(fn)
    names = list(sig.parameters)
    at = names.index("settings_options")
    generated = settings_parameters()
    own = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in sig.parameters.values()]

    @functools.wraps(fn)
    def command(**kw):
        opts = {p.name: kw.pop(p.name) for p in generated}
        return fn(**kw, settings_options=opts)

    hints = typing.get_type_hints(fn)  # the command's own annotations, resolved in its module
    own = [p.replace(annotation=hints.get(p.name, p.annotation)) for p in own]
    params = own[:at] + generated + own[at + 1:]
    command.__signature__ = sig.replace(parameters=params)
    command.__annotations__ = {p.name: p.annotation for p in params} | {"return": None}
    del command.__wrapped__  # typer reads __signature__, not the wrapped function's
    return command


def render_settings(opts: dict, *, scenes: Iterable = (), flag: Callable[[str], str] = cli_flag):
    """The :class:`RenderSettings` of ``opts`` (field → value; ``None`` for an option left at its
    default), after the checks that need the scenes (a stratified render needs ``4 * spp`` ≥ the
    bands). A noise target implies adaptive spp. Raises :class:`UserError` (or
    :class:`~scene.schema.SceneError` from the settings' own checks, which the caller
    reports as one line)."""
    from illumix.renderer_jobs.render_settings import RenderSettings

    opts = {k: v for k, v in opts.items() if v is not None or k == "denoise"}
    spp, wavelengths = opts.get("spp", 64), opts.get("wavelengths", "all-bands")
    for s in scenes:
        if 4 * spp < s.spectral_grid.n_bands and wavelengths == "stratified" and opts.get("backend") in (None, "mitsuba"):
            raise UserError(f"{flag('spp')} {spp} is too low: stratified sampling of {s.spectral_grid.n_bands} "
                            f"bands needs spp >= {-(-s.spectral_grid.n_bands // 4)}")
    target = opts.get("noise_target")
    if target is not None and not 0 < target < 1:
        raise UserError(f"{flag('noise-target')} {target} must lie in (0, 1): a relative standard deviation, "
                        "e.g. 0.05 for 5 %")
    opts["adaptive"] = opts.get("adaptive", False) or target is not None  # a target spreads paths by the pilot
    settings = RenderSettings(**opts)
    if "boost_reach" in opts and settings.boost_factor == 1:
        raise UserError(f"{flag('boost-reach')} chooses where the targeted extra paths go, but there are none "
                        f"here ({flag('boost-factor')} 1, or not all-bands with denoise dt-irradiance); drop it")
    return settings
