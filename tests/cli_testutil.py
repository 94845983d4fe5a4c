"""Running ``illumix`` in-process for CLI tests: exit code and captured output."""

from __future__ import annotations

from illumix.cli import main


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``illumix ARGV`` in this process: ``(exit code, stdout, stderr)`` of that call alone."""
    capsys.readouterr()
    try:
        main(list(argv))
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err
