"""Pre-flight checks of output locations, before any computation starts.

A job that simulates for minutes and then cannot write its result wastes the minutes and, worse,
tells the user late. :func:`check_output` therefore makes sure, up front, that an output file's
folder exists (or can be created), that a file can really be created there (a probe file: this
catches read-only mounts, missing permissions and a full inode table alike, where ``os.access``
would not), and that the file system has room for the expected size. Every failure is a
:class:`~gearsim.errors.UsageError`: one line naming the folder and the cause (exit 2).
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from gearsim.errors import UsageError

__all__ = [
    "check_folder", "check_output", "check_outputs", "failed_job_logs", "free_bytes", "os_cause",
    "write_text_atomic",
]

#: Free space asked of a file system when the caller gives no estimate (bytes): room for a small
#: result file and its temporary copy.
DEFAULT_NEED = 1 << 20

_HINTS = {
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
}


def os_cause(exc: OSError) -> str:
    """The cause of an OSError in a few words (no file name, no errno number)."""
    return _HINTS.get(exc.errno or 0) or exc.strerror or " ".join(str(exc).split())


def free_bytes(folder: str | Path) -> int:
    """Bytes an unprivileged writer may still use on the file system of ``folder``."""
    st = os.statvfs(folder)
    return int(st.f_bavail) * int(st.f_frsize)


def _human(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"  # pragma: no cover


def check_output(path: str | Path, *, need: int = DEFAULT_NEED, what: str = "output") -> Path:
    """Check that ``path`` (a file to be written) can be written, before any work is done.

    Creates the file's folder if needed, creates and removes a probe file in it and asks for
    ``need`` free bytes on its file system (twice the result's size is a safe estimate: the
    writers write a temporary file and rename it). ``path`` itself must not be a folder.
    Raises :class:`UsageError` naming the folder or file and the cause. Returns ``path``.
    """
    path = Path(path)
    folder = path.parent
    if path.is_dir():
        raise UsageError(f"{what} {path}: is a folder, expected a file name")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UsageError(f"{what} {path}: {folder} exists and is not a folder") from None
    except OSError as exc:
        raise UsageError(
            f"{what} {path}: cannot create folder {folder} ({os_cause(exc)})"
        ) from None
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UsageError(f"{what} {path}: cannot write in {folder} ({os_cause(exc)})") from None
    free = free_bytes(folder)
    if free < need:
        raise UsageError(
            f"{what} {path}: only {_human(free)} free in {folder}, about {_human(need)} needed "
            "(free space and re-run)"
        )
    return path


def check_folder(folder: str | Path, *, need: int = DEFAULT_NEED,
                 what: str = "output folder") -> Path:
    """:func:`check_output` for a folder: it exists or can be made, a file can be created in it
    and ``need`` bytes are free. The message names the folder."""
    folder = Path(folder)
    try:
        check_output(folder / ".gearsim-probe", need=need, what=what)
    except UsageError as exc:
        msg = str(exc).replace(f"{what} {folder / '.gearsim-probe'}: ", f"{what} {folder}: ")
        raise UsageError(msg.replace(f"cannot write in {folder} ", "cannot write in it ")
                         ) from None
    return folder


def check_outputs(paths: Iterable[str | Path], *, need: int = DEFAULT_NEED,
                  what: str = "output") -> None:
    """:func:`check_output` for each of ``paths`` (folders checked once)."""
    seen: set[Path] = set()
    for p in paths:
        p = Path(p)
        if p.parent.resolve() in seen:
            if p.is_dir():
                raise UsageError(f"{what} {p}: is a folder, expected a file name")
            continue
        check_output(p, need=need, what=what)
        seen.add(p.parent.resolve())


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file renamed into place: a full disk or a
    killed process leaves the previous file whole and no temporary file behind."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


#: Snakemake's line naming a failed job's log (``    log: logs/x.log (check log file(s) ...)``)
_FAILED_LOG = "log: "
_FAILED_LOG_END = " (check log file"


def failed_job_logs(snakemake_log: str | Path | Iterable[str | Path],
                    run_folder: str | None) -> list[str]:
    """Lines naming the log of every failed job of a run (``snakemake_log``: Snakemake's log
    file, or its list of them), as paths to open from the project folder (where the run was
    started): Snakemake names them relative to the folder the run works in, which for a study
    of one's own (or a ``folder:``) is ``studies/<folder>/``. Empty for a run in the project
    folder itself (its paths are right as they stand) or when the log names none."""
    if run_folder is None:
        return []
    logs = [snakemake_log] if isinstance(snakemake_log, str | Path) else list(snakemake_log)
    text = ""
    for log in logs:  # Snakemake 9 passes its log files as a list
        try:
            text += Path(log).read_text(errors="replace") + "\n"
        except OSError:
            continue
    out: list[str] = []
    rule = ""
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("Error in rule ") and stripped.endswith(":"):
            rule = stripped[len("Error in rule "):-1]
        elif stripped.startswith(_FAILED_LOG) and _FAILED_LOG_END in stripped:
            names = stripped[len(_FAILED_LOG):stripped.index(_FAILED_LOG_END)]
            for name in (n.strip() for n in names.split(",")):
                where = name if Path(name).is_absolute() else f"studies/{run_folder}/{name}"
                entry = f"log of the failed job{f' {rule}' if rule else ''}: {where}"
                if entry not in out:
                    out.append(entry)
    return out
