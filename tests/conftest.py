import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parent))


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """The whole workflow on config/tiny.yaml (2 cores, 4-row tiles), run once per session."""
    from workflow_helpers import make_workdir, smk, targets

    wd = make_workdir(tmp_path_factory.mktemp("tiny"))
    tg = targets(wd, "config/tiny.yaml")
    r = smk(wd, *tg, "--cores", "2", "--configfile", "config/tiny.yaml")
    return wd, tg, r
