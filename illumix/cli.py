"""``illumix`` — entry point. Sub-commands live in ``illumix/cmd_*.py`` and register here.

Every expected failure (bad name, bad file, bad parameter) ends as one line on stderr and exit
code 2 — never a traceback.
"""

from __future__ import annotations

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
    from illumix import cmd_serve, cmd_spectra

    cmd_spectra.register(app)
    from illumix import cmd_store; cmd_store.register(app)
    cmd_serve.register(app)
    from illumix import cmd_render, cmd_validate
    cmd_render.register(app)
    cmd_validate.register(app)


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; map expected errors to one stderr line and exit 2."""
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
    except Exception as exc:  # click usage errors and the like
        import click

        if isinstance(exc, click.ClickException):
            print(f"illumix: error: {exc.format_message()}", file=sys.stderr)
            sys.exit(2)
        raise


if __name__ == "__main__":
    main()
