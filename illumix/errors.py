"""Errors the CLI reports as one line (exit 2)."""


class UserError(Exception):
    """A problem with what the user asked for; the message says what, where and how to fix it."""
