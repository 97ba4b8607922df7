import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# tests/ and its tier folders are import roots: shared helpers (reference.py, tiny_study.py, ...)
# and the helpers one test file takes from another, across tiers
for _folder in ("workflow", "integration", "unit", ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent / _folder))


import pytest  # noqa: E402

# Parallel runs (`make test`: pytest-xdist, `-n 2 --dist loadfile`). Every test file is one
# scheduling unit, so its module-scoped fixtures are built once, on one worker. Files that share a
# session-scoped study are one unit, so the study is built once (the scheduler below):
SHARED_GROUPS = {
    # tiny_run below: the whole workflow on config/tiny.yaml
    "test_pipeline.py": "tiny_run",
    "test_catalogue_integrity.py": "tiny_run",
    "test_trust_runs.py": "tiny_run",
    "test_results_in_place.py": "tiny_run",
    "test_readme_beside_a_study.py": "tiny_run",
    # tests/tiny_study.py: the tiny study with a (w, eps) plane, under the worker's basetemp
    "test_figures_planes.py": "tiny_study",
    "test_explorer.py": "tiny_study",
    "test_report_study.py": "tiny_study",
    "test_kmax_one.py": "tiny_study",
    "test_labdb.py": "tiny_study",
}
# Units handed out first, longest first, so the last units to start are short ones and both
# workers finish close together; units not named here follow in collection order. CPU seconds
# (test + waited subprocesses) from a parallel run on a loaded machine:
# tiny_run >= 240 (its fixture 190), test_attractors_pipeline 139, test_cluster 33; the rest of
# this list runs whole pipelines or a fresh compile too, ordered by what they run.
LONGEST_FIRST: tuple[str, ...] = (
    # the tiny workflow through SLURM (~370 s, mostly waiting on the scheduler's status queries):
    # first, on one worker, while the other runs tiny_run, which it compares with at its end
    # (workflow_helpers.tiny_run_once: one run for both workers)
    "test_slurm.py",
    "tiny_run",  # the tiny workflow, then rebuilds, dry runs and a killed-and-resumed run
    "test_one_source.py",  # compiles a modified copy of the package from an empty cache
    "test_attractors_equivalence.py",  # two finders on a 40 x 40 plane, 16 starts per cell
    "test_attractors_pipeline.py",
    "tiny_study",
    "test_portable.py",  # compiles the kernels for AVX2 in a fresh cache
    "test_pipeline_study.py",
    "test_readme.py",
    "test_trust_config.py",
    "test_trust_input.py",
    "test_cluster.py",
)


def _unit(path: str) -> str:
    name = Path(path).name
    return SHARED_GROUPS.get(name, name)


@pytest.hookimpl(tryfirst=True, optionalhook=True)  # optional: without xdist, no error
def pytest_xdist_make_scheduler(config, log):
    """`--dist loadfile` with the shared-study files of SHARED_GROUPS as one unit each.

    (xdist's own `loadgroup` marks do not group under pytest 9: xdist 3.8 renames
    `item._nodeid`, which pytest 9 no longer reads.)
    """
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SharedStudyScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid.split("::", 1)[0])

    config.option.loadscopereorder = False  # keep the order set below
    return SharedStudyScheduling(config, log)


#: The tiers (folders of tests/): unit runs in seconds per file (`make test-fast`), integration runs
#: the compiled kernels over longer horizons or a subprocess, workflow runs Snakemake. Each test is
#: marked with its tier, so `pytest -m "not workflow"` selects by tier too.
TIERS = ("unit", "integration", "workflow")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark every test with its tier; on xdist workers, put the units of LONGEST_FIRST first (the
    scheduler follows this order). A plain `pytest` run keeps the files in collection order.
    """
    for it in items:
        tier = Path(str(it.fspath)).parent.name
        if tier in TIERS:
            it.add_marker(getattr(pytest.mark, tier))
    if not hasattr(config, "workerinput") or not LONGEST_FIRST:
        return
    rank = {u: i for i, u in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda it: rank.get(_unit(str(it.fspath)), len(rank)))  # stable


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """:func:`workflow_helpers.tiny_run_once` as a fixture (the files of its SHARED_GROUPS
    unit)."""
    from workflow_helpers import tiny_run_once

    return tiny_run_once(tmp_path_factory)
