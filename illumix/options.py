"""Options shared by several commands, built so that ``--help`` needs no heavy import.

An option over a method family (:class:`retarget.registry.MethodRegistry`) accepts every spelling
the family accepts (case, spaces, hyphens, aliases) and hands the command the canonical name; its
choices show in ``--help``; anything else is a usage error (exit 2) naming the valid choices and
the close matches.
"""

from __future__ import annotations

from typing import Any

import typer

from illumix.renderer_jobs.modes import WAVELENGTH_MODES
from illumix.retarget.errors import UnknownName
from illumix.retarget.registry import MethodRegistry

# The renderer hashes seeds to 32 bits, so --seed N and N + 2**32 would give the same cube.
SEED_MAX = 2**32 - 1


def choice_option(registry: MethodRegistry, flag: str, help: str, default: str | None = None) -> Any:
    """A typer option taking one name of ``registry`` (default: its first name)."""

    def parse(value: str) -> str:
        try:
            return registry.canonical(value)
        except UnknownName as exc:
            raise typer.BadParameter(str(exc)) from None

    return typer.Option(default or registry.names[0], flag, parser=parse,
                        metavar=f"[{'|'.join(registry.choices())}]", help=help)


def described(registry: MethodRegistry[str]) -> str:
    """``"a: what a does; b: what b does"`` for a family whose values are descriptions."""
    return "; ".join(f"{name}: {what}" for name, what in registry.items())


def wavelengths_option() -> Any:
    return choice_option(WAVELENGTH_MODES, "--wavelengths", f"Wavelength sampling — {described(WAVELENGTH_MODES)}.")


def seed_option(flag: str, help: str) -> Any:
    return typer.Option(0, flag, min=0, max=SEED_MAX, help=help)
