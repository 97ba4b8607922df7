"""The ``gearsim`` command line: one subcommand per module in :mod:`gearsim.cli.commands`.

Each module there defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``;
modules are discovered automatically, so a new subcommand is one new file.
Bad input and faults of the machine or of the files (full disk, read-only folder, missing
permission, a file that is not what its name says) exit with status 2 and one line on stderr
naming the file and the cause, never a traceback (set ``GEARSIM_DEBUG=1`` to get the traceback
of a machine or file fault).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pkgutil
import sys

from gearsim import __version__
from gearsim.cli import commands
from gearsim.errors import USER_ERRORS, UsageError, one_line

__all__ = ["UsageError", "build_parser", "main"]

#: Set (to anything) to get the traceback of a machine or file fault instead of its one line.
DEBUG_ENV = "GEARSIM_DEBUG"

#: what `gearsim --help` says first (plain words: it is printed, not rendered)
DESCRIPTION = ("gearsim: the nonlinear dynamics of a curve-face gear pair over parameter planes, "
               "sweeps and points. `gearsim COMMAND --help` describes one command.")

def _subcommand_modules(only: str | None = None):
    if only is not None:
        # the command named on the command line alone, when its module is commands/<name>.py:
        # a pipeline job then imports what its command needs, not every command's libraries
        # (scipy.optimize, SQLAlchemy, matplotlib: ~1 s of CPU per job); else all of them
        name = only.replace("-", "_")
        if name.isidentifier() and importlib.util.find_spec(f"{commands.__name__}.{name}"):
            mod = importlib.import_module(f"{commands.__name__}.{name}")
            if getattr(mod, "NAME", None) == only:
                yield mod
                return
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        yield importlib.import_module(f"{commands.__name__}.{info.name}")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2
        sys.stderr.write(f"gearsim: error: {message}\n")
        raise SystemExit(2)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    parser = _Parser(prog="gearsim", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"gearsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for mod in _subcommand_modules(only):
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    only = argv[0] if argv and not argv[0].startswith("-") else None
    parser = build_parser(only)
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except USER_ERRORS as exc:
        sys.stderr.write(f"gearsim {args.command}: error: {one_line(exc)}\n")
        return 2
    except BrokenPipeError:
        # the reader went away (`gearsim ... | head`): stop quietly, as `cat` does
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as exc:
        if os.environ.get(DEBUG_ENV):
            raise
        sys.stderr.write(f"gearsim {args.command}: error: {os_error_line(exc)}\n")
        return 2
    except MemoryError:
        sys.stderr.write(f"gearsim {args.command}: error: out of memory\n")
        return 2
    except Exception as exc:
        line = _file_fault_line(exc)
        if line is None or os.environ.get(DEBUG_ENV):
            raise  # a bug: the traceback is what a developer needs
        sys.stderr.write(f"gearsim {args.command}: error: {line}\n")
        return 2


def os_error_line(exc: OSError) -> str:
    """``<file>: <cause>`` of an OSError, on one line."""
    from gearsim.study.preflight import os_cause

    names = [str(n) for n in (exc.filename, exc.filename2) if n is not None]
    where = f"{' -> '.join(names)}: " if names else ""
    return f"{where}{os_cause(exc)}"


def _file_fault_line(exc: Exception) -> str | None:
    """One line for a file that is not what its name says (Parquet, SQLite, YAML), else None.

    The commands name the file when they can; this is the net under them."""
    import sqlite3

    mod = type(exc).__module__ or ""
    if mod.startswith("pyarrow") or isinstance(exc, sqlite3.DatabaseError):
        return f"unreadable file ({type(exc).__name__}: {one_line(exc)})"
    if mod.startswith("yaml"):
        return f"invalid YAML ({one_line(exc)})"
    if mod.startswith("sqlalchemy.exc"):
        orig = getattr(exc, "orig", None)
        return f"database fault ({one_line(orig if orig is not None else exc)})"
    return None


if __name__ == "__main__":
    raise SystemExit(main())
