"""The command line around every command: Ctrl-C ends a command in one line (what was kept, the
command that resumes it) with exit status 130 and no traceback; a first run says that it
compiles the kernels, once, and about how long; the kernels' cache is .numba_cache/ of the
checkout unless NUMBA_CACHE_DIR says otherwise."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from gearsim.cli import main as cli
from gearsim.cli.commands import query

ROOT = Path(__file__).resolve().parents[2]


def test_ctrl_c_is_one_line_with_the_command_that_resumes(monkeypatch, capsys):
    def stopped(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(query, "run", stopped)
    argv = ["query", "--catalogue", "my results/catalogue.sqlite", "--format", "csv"]
    assert cli.main(argv) == cli.INTERRUPTED == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"gearsim query: interrupted; {cli.KEPT}; run the same command")
    assert err.rstrip().endswith(
        "gearsim query --catalogue 'my results/catalogue.sqlite' --format csv")  # as typed, quoted
    # a command that says what it keeps
    monkeypatch.setattr(query, "kept", lambda args: "the cells done so far are kept in X",
                        raising=False)
    assert cli.main(argv) == 130
    assert "interrupted; the cells done so far are kept in X; run" in capsys.readouterr().err


def test_ctrl_c_ends_an_open_progress_line_first(monkeypatch):
    """On a terminal the progress line is rewritten in place; the interruption's line starts on
    a line of its own."""
    from gearsim.cli.commands._progress import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    monkeypatch.setattr(sys, "stderr", tty)

    def stopped(args):
        p = Progress("job", 10, stream=tty, interval=0)
        p(3, 10, 1.0)
        raise KeyboardInterrupt

    monkeypatch.setattr(query, "run", stopped)
    assert cli.main(["query", "--format", "csv"]) == 130
    lines = tty.getvalue().split("\n")
    assert lines[0].startswith("\r[") and "3/10 cells" in lines[0]
    assert lines[1].startswith("gearsim query: interrupted;") and lines[2] == ""


def test_sigint_in_a_real_process_exits_130_without_traceback(tmp_path):
    """SIGINT delivered to a running `gearsim` process (the shell's Ctrl-C)."""
    script = textwrap.dedent("""
        import os, signal, sys, time
        from gearsim.cli import main as cli
        from gearsim.cli.commands import query
        def run(args):
            print("started", flush=True)
            time.sleep(30)
        query.run = run
        sys.exit(cli.main(["query", "--format", "csv"]))
    """)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    # SIGINT as a terminal delivers it (a shell's background job would inherit it ignored)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stdout.readline().strip() == "started"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert "run the same command to resume: gearsim query --format csv" in err


def test_first_compile_says_what_and_how_long(monkeypatch):
    """With no cached kernel, the first Numba compile prints one line (once); with a warm cache
    nothing is said and nothing is registered."""
    from numba import njit
    from numba.core import event

    monkeypatch.setattr(cli, "_cache_is_cold", lambda: False)
    assert cli.announce_compile(io.StringIO()) is None
    monkeypatch.setattr(cli, "_cache_is_cold", lambda: True)
    out = io.StringIO()
    notice = cli.announce_compile(out)
    try:
        njit(lambda x: x + 1)(1)
        njit(lambda x: x * 2.5)(1.0)
    finally:
        event.unregister("numba:compile", notice)
    lines = out.getvalue().splitlines()
    assert len(lines) == 1, lines
    # a command run in-process leaves no listener behind (its stream may be gone)
    from gearsim.cli.commands import query

    monkeypatch.setattr(query, "run", lambda args: njit(lambda x: x - 3)(3))  # 0: success
    before = len(event._registered["numba:compile"])
    assert cli.main(["query", "--format", "csv"]) == 0
    assert len(event._registered["numba:compile"]) == before
    assert lines[0].startswith("gearsim: compiling the numerical kernels for this CPU, once: "
                               f"about {cli.COMPILE_SECONDS} s")
    assert "later runs load them from" in lines[0]


def test_numba_cache_defaults_to_the_checkout(monkeypatch):
    """Without NUMBA_CACHE_DIR the command line caches the kernels in .numba_cache/ of the
    checkout (what the README and the Makefile say); a user's setting is kept."""
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    cli._set_cache_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == str(ROOT / ".numba_cache")
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere/else")
    cli._set_cache_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == "/somewhere/else"
