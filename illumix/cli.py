"""``illumix`` — entry point. Sub-commands live in ``illumix/cmd_*.py`` and register here.

Every expected failure (bad name, bad file, bad parameter, a full, read-only or failing disk) ends
as one line on stderr and exit code 2 — never a traceback. A command that finds a problem
(``store verify``) exits 1.

Registering the commands must stay cheap — ``illumix --help`` and ``illumix CMD --help`` import
typer, rich and the pure-Python option registries only: the ``cmd_*`` modules import numpy,
colour-science, zarr, Mitsuba and the service inside the commands (tests/test_cli_startup.py).
"""

from __future__ import annotations

import os
import sys

import typer

from illumix.errors import STORAGE_ERRNOS, UserError, storage_errno

app = typer.Typer(
    name="illumix",
    help="Exact mixed-illuminant colour-constancy data from spectral transport cubes.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # plain click help: rendering rich tables cost ~0.2 s of every --help
)


def _version(value: bool) -> None:
    if not value:
        return
    from importlib.metadata import PackageNotFoundError, version

    try:
        print(f"illumix {version('illumix')}")
    except PackageNotFoundError:  # a source tree on sys.path, never pip-installed
        print("illumix (version unknown: not installed; pip install -e .)")
    raise typer.Exit()


@app.callback()
def _root(show_version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                            help="Print the version and exit.")) -> None:
    """Options before the command (the app's help text is set on ``app``)."""


def _register() -> None:
    if app.registered_commands:  # main() runs many times in one process in the tests
        return
    from illumix import (cmd_dataset, cmd_demo, cmd_evaluate, cmd_export, cmd_import, cmd_render, cmd_scenes,
                         cmd_serve, cmd_spectra, cmd_store, cmd_validate)

    for module in (cmd_spectra, cmd_store, cmd_render, cmd_import, cmd_validate, cmd_serve, cmd_demo, cmd_scenes,
                   cmd_dataset, cmd_export, cmd_evaluate):
        module.register(app)
    _whole_summaries(app)


def _whole_summaries(typer_app: typer.Typer) -> None:
    """Each command's and group's line in its parent's ``--help``: :func:`summary`, not click's cut."""
    for info in typer_app.registered_commands:
        if info.short_help is None:
            info.short_help = summary(info.help or info.callback.__doc__ or "")
    for group in typer_app.registered_groups:
        if isinstance(group.typer_instance.info.help, str):
            group.short_help = summary(group.typer_instance.info.help)
        _whole_summaries(group.typer_instance)


def summary(doc: str) -> str:
    """A command's line in ``illumix --help``: its docstring's first sentence, whole. Click's default
    cuts it at 45 characters or at the first ``.`` (``(thesis eq.``); an explicit short help is wrapped
    instead. A sentence ends at ``. `` before a capital letter, or at the paragraph's end."""
    text = " ".join(doc.strip().split("\n\n")[0].split())
    for i in range(len(text) - 2):
        if text[i] == "." and text[i + 1] == " " and text[i + 2].isupper():
            return text[:i + 1]
    return text


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; map expected errors to one stderr line and exit 2."""
    args = sys.argv[1:] if argv is None else argv
    if args[:1] in (["serve"], ["demo"]):
        # Measured (bench/PERFORMANCE.md): the service's tall-thin BLAS products run 1.2-2.1x more
        # requests/s with one BLAS thread per request thread. Must be set before numpy loads;
        # an explicit setting in the environment wins.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from illumix.retarget.errors import SpectralError

    _register()
    import warnings

    def one_line(message, category, filename, lineno, file=None, line=None) -> None:
        # what a scene import had to approximate, said in one line (not Python's file:line form)
        print(f"illumix: warning: {message}", file=sys.stderr)

    warnings.showwarning = one_line
    try:
        code = app(args=argv, prog_name="illumix", standalone_mode=False)
    except (SpectralError, UserError) as exc:
        print(f"illumix: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except typer.Abort:
        print("illumix: aborted", file=sys.stderr)
        sys.exit(130)
    except Exception as exc:
        # A store that is damaged or missing something: the store's errors are one line by contract.
        # Looked up among the loaded modules (a StoreError exists only once store/ is imported), so
        # --help never imports zarr.
        store_errors = sys.modules.get("illumix.store.errors")
        if store_errors is not None and isinstance(exc, store_errors.StoreError):
            print(f"illumix: error: {exc}", file=sys.stderr)
            sys.exit(2)
        if isinstance(exc, OSError) and storage_errno(exc) is not None:  # a full, read-only or failing disk
            print(f"illumix: error: {storage_line(exc)}", file=sys.stderr)
            sys.exit(2)
        # Usage errors (missing option, unknown command): typer ships its own copy of click, so
        # recognise them by what they can do rather than by class.
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            message = exc.format_message()
            if type(exc).__name__ == "NoArgsIsHelpError":  # `illumix` / `illumix store` alone: the help
                print(message)
            elif message:
                print(f"illumix: error: {message}", file=sys.stderr)
            sys.exit(2)
        raise
    # With standalone_mode=False click *returns* the code of a `typer.Exit` raised in a command
    # (and turns Ctrl-C into 130) instead of exiting: pass it on, or `store verify` finding problems
    # and an interrupted render would both exit 0.
    if code == 130:
        print("illumix: interrupted", file=sys.stderr)
    if isinstance(code, int) and code:
        sys.exit(code)


def storage_line(exc: OSError) -> str:
    """What a storage error (:func:`illumix.errors.storage_errno`) no command words itself says: the
    file, why, and what to do."""
    n = storage_errno(exc)
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{os.strerror(n)}; {STORAGE_ERRNOS[n].format(elsewhere='use another location')}, then run " \
           "the command again"


if __name__ == "__main__":
    main()
