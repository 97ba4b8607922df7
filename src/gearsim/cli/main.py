"""The ``gearsim`` command line: one subcommand per module in :mod:`gearsim.cli.commands`.

Each module there defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``;
modules are discovered automatically, so a new subcommand is one new file. A long command may
also define ``kept(args) -> str``: what an interrupted run of it keeps (Ctrl-C, below).
Bad input and faults of the machine or of the files (full disk, read-only folder, missing
permission, a file that is not what its name says) exit with status 2 and one line on stderr
naming the file and the cause, never a traceback (set ``GEARSIM_DEBUG=1`` to get the traceback
of a machine or file fault).

Ctrl-C (SIGINT) in any command ends it with one line -- what was kept (the command's
``kept(args)``, else :data:`KEPT`) and the command line that resumes it -- and exit status 130,
never a traceback. The kernels' first compile says what it is doing and about how long it takes
(:func:`announce_compile`); their cache is ``NUMBA_CACHE_DIR``, by default ``.numba_cache/`` of
the source checkout (:func:`default_cache_dir`).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pkgutil
import shlex
import sys
from pathlib import Path

from gearsim import __version__
from gearsim.cli import commands
from gearsim.errors import USER_ERRORS, UsageError, one_line

__all__ = ["UsageError", "build_parser", "main"]

#: Set (to anything) to get the traceback of a machine or file fault instead of its one line.
DEBUG_ENV = "GEARSIM_DEBUG"

#: what `gearsim --help` says first (plain words: it is printed, not rendered)
DESCRIPTION = ("gearsim: the nonlinear dynamics of a curve-face gear pair over parameter planes, "
               "sweeps and points. `gearsim COMMAND --help` describes one command.")

#: What an interrupted command keeps when it does not say (its outputs are written to a temporary
#: name and renamed when complete: a file it was writing is not left half-written)
KEPT = "files it had finished are kept; none is left half-written"
#: Exit status of a command stopped by Ctrl-C (128 + SIGINT, as the shell reports it)
INTERRUPTED = 130
#: About how long the kernels' first compile takes, what the notice before it says (41 s of CPU
#: for the first ``gearsim point`` of an empty cache on an AMD EPYC; docs/decisions.md)
COMPILE_SECONDS = 40


def default_cache_dir() -> Path | None:
    """``.numba_cache/`` of the source checkout this package runs from (where the Makefile and
    the workflow put it), None for an installed package (Numba's own default then)."""
    root = Path(__file__).resolve().parents[3]
    return root / ".numba_cache" if (root / "pyproject.toml").is_file() else None


def _set_cache_dir() -> None:
    """Point ``NUMBA_CACHE_DIR`` at :func:`default_cache_dir` unless the user set it (before
    Numba is imported; the check for stale kernels then looks there too)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    default = default_cache_dir()
    if default is None:
        return
    os.environ["NUMBA_CACHE_DIR"] = str(default)
    from gearsim.numerics.cache import invalidate_stale_cache

    invalidate_stale_cache()


def _cache_is_cold() -> bool:
    """Whether no compiled kernel of the numerics is cached yet (a first run)."""
    from gearsim.numerics.cache import cache_directory

    numerics = Path(__file__).resolve().parents[1] / "numerics"
    cache = cache_directory(numerics)
    return not any(cache.glob("*.nbi"))


def announce_compile(stream=None):
    """On a first run (no cached kernel), say so in one line when Numba starts compiling: what
    it does, about how long, and where the result is kept for later runs. Returns the
    listener (None on a warm cache)."""
    if not _cache_is_cold():
        return None
    from numba.core import event

    cache = os.environ.get("NUMBA_CACHE_DIR") or "the package's __pycache__ folders"

    class _Notice(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                try:  # a notice: it never stops the compile
                    print(f"gearsim: compiling the numerical kernels for this CPU, once: about "
                          f"{COMPILE_SECONDS} s on a free core, longer on a busy machine (later "
                          f"runs load them from {cache})", file=stream or sys.stderr,
                          flush=True)
                except (OSError, ValueError):
                    pass

        def on_end(self, ev):
            pass

    notice = _Notice()
    event.register("numba:compile", notice)
    return notice


def _end_notice(notice) -> None:
    """Unregister :func:`announce_compile`'s listener (a command run in-process, as the tests
    do, leaves none behind)."""
    if notice is not None:
        from numba.core import event

        event.unregister("numba:compile", notice)


def _resume_line(argv: list[str]) -> str:
    return "gearsim " + shlex.join(argv)


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
        p.set_defaults(_run=mod.run, _kept=getattr(mod, "kept", None))
    return parser


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    only = argv[0] if argv and not argv[0].startswith("-") else None
    try:
        _set_cache_dir()
        parser = build_parser(only)
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        sys.stderr.write("\ngearsim: interrupted before the command started; nothing was "
                         "written\n")
        return INTERRUPTED
    notice = None
    try:
        notice = announce_compile()
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        return interrupted(args, argv)
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
    finally:
        _end_notice(notice)


def interrupted(args: argparse.Namespace, argv: list[str]) -> int:
    """The end of a command stopped by Ctrl-C: one line saying what was kept and the command
    that resumes it; :data:`INTERRUPTED`."""
    from gearsim.cli.commands._progress import end_line

    end_line()
    kept = KEPT
    if args._kept is not None:
        try:
            kept = args._kept(args)
        except Exception:  # noqa: BLE001 - the line must come out whatever the command's state
            kept = KEPT
    sys.stderr.write(f"gearsim {args.command}: interrupted; {kept}; run the same command to "
                     f"resume: {_resume_line(argv)}\n")
    sys.stderr.flush()
    return INTERRUPTED


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
