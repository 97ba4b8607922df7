"""Exceptions that the CLI turns into one-line errors with exit status 2."""

from __future__ import annotations

from .parameters import ParameterError


class UsageError(Exception):
    """Bad user input detected by a subcommand (exit status 2, one line)."""


USER_ERRORS = (ParameterError, UsageError)
