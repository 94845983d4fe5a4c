"""``illumix`` — entry point. Sub-commands live in ``illumix/cmd_*.py`` and register here.

Every expected failure (bad name, bad file, bad parameter) ends as one line on stderr and exit
code 2 — never a traceback.
"""

from __future__ import annotations

import os
import sys

import typer

from illumix.errors import UserError

app = typer.Typer(
    name="illumix",
    help="Exact mixed-illuminant colour-constancy data from spectral transport cubes.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _register() -> None:
    from illumix import cmd_demo, cmd_render, cmd_serve, cmd_spectra, cmd_store, cmd_validate

    for module in (cmd_spectra, cmd_store, cmd_render, cmd_validate, cmd_serve, cmd_demo):
        module.register(app)


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; map expected errors to one stderr line and exit 2."""
    args = sys.argv[1:] if argv is None else argv
    if args[:1] in (["serve"], ["demo"]):
        # Measured (bench/PERFORMANCE.md): the service's tall-thin BLAS products run 1.2-2.1x more
        # requests/s with one BLAS thread per request thread. Must be set before numpy loads;
        # an explicit setting in the environment wins.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from retarget.errors import SpectralError

    _register()
    try:
        app(args=argv, standalone_mode=False)
    except (SpectralError, UserError) as exc:
        print(f"illumix: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        print("illumix: aborted", file=sys.stderr)
        sys.exit(130)
    except KeyboardInterrupt:
        print("illumix: interrupted", file=sys.stderr)
        sys.exit(130)
    except Exception as exc:
        # Usage errors (missing option, unknown command): typer ships its own copy of click, so
        # recognise them by what they can do rather than by class.
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            print(f"illumix: error: {exc.format_message()}", file=sys.stderr)
            sys.exit(2)
        raise


if __name__ == "__main__":
    main()
