"""Exceptions that the CLI turns into one-line errors with exit status 2.

Library modules raise these (never import :mod:`gearsim.cli`); :func:`gearsim.cli.main.main` prints
``gearsim <command>: error: <message>`` and exits with status 2. This module imports nothing of
the package: every layer may raise these.
"""

from __future__ import annotations


class ParameterError(ValueError):
    """A parameter is outside its allowed range. The message names the parameter and the range."""


class UsageError(Exception):
    """Bad user input detected by a subcommand (exit status 2, one line)."""


class ConfigError(ParameterError):
    """The pipeline configuration is invalid; the message names the offending key."""


class CatalogueError(UsageError):
    """A tile, plane file or catalogue is unusable; one line naming it (CLI: exit 2)."""


USER_ERRORS = (ParameterError, UsageError)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (its type's name when it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def reject_unknown(keys, allowed, what: str) -> None:
    """Raise :class:`ParameterError` for the first of ``keys`` not in ``allowed``, naming it
    (as ``what``) and every allowed name in ``allowed``'s order."""
    for key in keys:
        if key not in allowed:
            raise ParameterError(f"unknown {what} '{key}'; allowed: {', '.join(allowed)}")
