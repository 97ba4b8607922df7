# Config validation, tile list, shared helpers. Everything here runs once when the workflow is
# parsed, before any job starts.
import os
import sys

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid
from gearsim.results import in_place as gin
from gearsim.study import provenance as gprov
from gearsim.study import figure_tables as gfd

SCHEMA = Path(workflow.basedir) / "workflow/schemas/config.schema.yaml"

# 1. The study's configuration, resolved as the gearsim CLI resolves it
#    (gearsim.study.config.study_config): the config files in Snakemake's order, then the `--config`
#    overrides, merged by gearsim.study.config.merge_study (a file that names a `study` brings its own
#    planes, sweeps and points instead of adding them to the paper's), validated with one clear
#    line naming a bad key, schema defaults filled. It replaces Snakemake's own merge.
STUDY_ROOT = Path.cwd().resolve()
_cli_files = [Path(f).resolve() for f in workflow.config_settings.configfiles]
_own_files = [Path(f).resolve() for f in workflow.configfiles]
_own_files = [f for f in _own_files if f not in _cli_files]
if getattr(workflow.config_settings, "replace_workflow_config", False):
    _own_files = []
# `--config replace_results=true`: this run may replace results that another configuration made
# (gearsim.results.in_place); an option of the run, not of the study, so not part of its config
_overrides = dict(workflow.config_settings.config or {})
_replace = _overrides.pop(gin.REPLACE_KEY, False)
REPLACE_RESULTS = {True: True, False: False, "true": True, "false": False}.get(
    _replace.lower() if isinstance(_replace, str) else _replace)
if REPLACE_RESULTS is None:
    raise WorkflowError(f"--config {gin.REPLACE_KEY}: true or false, not {_replace!r}")
try:
    _resolved = gcfg.load_config(
        _own_files + _cli_files,
        _overrides or None,
        root=STUDY_ROOT,
    )
except gcfg.ConfigError as exc:
    raise WorkflowError(f"invalid configuration: {exc}") from None
STUDY_NAME = _resolved["study"]
# the folder under studies/ the run works in: a study's, or the `folder` of a variant of the
# paper's study (config/quick.yaml) that keeps its own results; None = this directory
RUN_FOLDER = gcfg.run_folder(_resolved)
if RUN_FOLDER is not None and _resolved["standard_parameters"] is not None:
    # a run in studies/<folder>/ (below): its file paths stay those of this directory
    _resolved["standard_parameters"] = str(
        gcfg.standard_parameters_path(_resolved, STUDY_ROOT).resolve()
    )
if RUN_FOLDER is not None and _resolved.get("gear"):
    _resolved["gear"] = str((STUDY_ROOT / _resolved["gear"]).resolve())
config.clear()
config.update(_resolved)
validate(config, str(SCHEMA))
# the one study object that every job definition asks for parameters and settings
STUDY = gcfg.Study.of(config, STUDY_ROOT)

# 2. How the jobs see the same config: one JSON file per study, rewritten only when its content
#    changes, passed with --configfile (merged over config/config.yaml it gives the same
#    config). Rules take it as an ancient() input: its name never changes (the same content
#    under another file name re-runs nothing) and its time never matters (the params below
#    decide what re-runs: editing one plane re-runs only that plane).
CONFIG_JSON = (
    STUDY_ROOT / ".snakemake" / "gearsim" / (RUN_FOLDER or "default") / "config.json"
)
_text = gprov.canonical_json(config)
if not CONFIG_JSON.is_file() or CONFIG_JSON.read_text() != _text:
    CONFIG_JSON.parent.mkdir(parents=True, exist_ok=True)
    _tmp = CONFIG_JSON.with_name(f"config.json.{os.getpid()}.tmp")
    _tmp.write_text(_text)
    os.replace(_tmp, CONFIG_JSON)
CONFIG = ancient(str(CONFIG_JSON))
# gearsim commands of the jobs resolve config/config.yaml and relative paths here (set by the
# workflow itself, not required from the user; the config JSON alone already gives the same
# configuration, this keeps relative paths of commands run inside studies/<study>/ right)
os.environ[gcfg.STUDY_ROOT_ENV] = str(STUDY_ROOT)

# A study of one's own (or a `folder`) keeps all its outputs (results/, logs/, Snakemake's
# records) in studies/<folder>/, so the paper's results/ is never touched (docs/pipeline.md,
# "Your own study").
if RUN_FOLDER is not None:
    if workflow.overwrite_workdir is not None:
        _what = f"study '{STUDY_NAME}'" if STUDY_NAME else f"folder '{RUN_FOLDER}'"
        raise WorkflowError(
            f"{_what} runs in studies/{RUN_FOLDER}/ of the project directory: run snakemake "
            "in the project directory without --directory/-d (it would override that folder)"
        )

    workdir: f"studies/{RUN_FOLDER}"


# The catalogue's two files. Snakemake deletes a job's declared outputs before the job starts,
# so the catalogue rule (workflow/rules/catalogue.smk) declares the build file and publishes it
# as the catalogue that readers open (hard link renamed into place): readers never see it missing
# or partial, and a failed rebuild keeps the last good one (docs/pipeline.md, Guarantees).
CATALOGUE_BUILD = "results/catalogue.d/build.sqlite"
PUBLISHED_CATALOGUE = "results/catalogue.sqlite"


# 3. Before any job: the output folders can be written (a read-only or full disk is one line
#    now, not a traceback after minutes of simulation), and a catalogue that readers would
#    refuse (damaged, foreign, of another schema version) is set aside so that the catalogue
#    rule rebuilds it from the verified Parquet files; readers never fall back silently.
_DRY_RUN = any(
    a in ("--dry-run", "--dryrun")
    or (a.startswith("-") and not a.startswith("--") and "n" in a)
    for a in sys.argv[1:]
)


def _preflight():
    from gearsim.errors import UsageError
    from gearsim.results.catalogue import set_aside_damaged
    from gearsim.study.preflight import check_folder

    if not _DRY_RUN:
        for folder in ("results", "logs"):
            try:
                check_folder(Path(folder).resolve())
            except UsageError as exc:
                # one line and exit 2, as the gearsim commands (a WorkflowError would add
                # Snakemake's file and line of this check)
                print(f"gearsim: error: {exc}", file=sys.stderr)
                raise SystemExit(2) from None
    # results that another configuration made are not replaced unasked (gearsim.results.in_place)
    try:
        gin.check_in_place(RUN_RECORD, "results", replace=REPLACE_RESULTS)
        # a tile no run of this folder computed: found now, before any job removes its plane
        gin.check_tiles_in_place(RUN_RECORD, "results")
    except UsageError as exc:
        print(f"gearsim: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    for line in set_aside_damaged(
        PUBLISHED_CATALOGUE, CATALOGUE_BUILD, dry_run=_DRY_RUN
    ):
        print(f"gearsim: {line}", file=sys.stderr)


RUN_RECORD = gin.run_record(STUDY, _own_files + _cli_files)
if workflow.is_main_process:  # not again in each job of a cluster executor
    _preflight()


onstart:
    # jobs are about to run (not a dry run, not "nothing to be done"): results/ is this run's now
    gin.write_record(RUN_RECORD, "results")


# 4. What the jobs depend on. CODE_VERSION[scope] hashes the layers a kind of job depends on
#    (gearsim.study.provenance.CODE_SCOPES): Snakemake does not see edits to a package.
CODE_VERSION = {scope: gprov.code_version(scope) for scope in gprov.CODE_SCOPES}
PLANES = list(config["planes"])
SWEEPS = list(config["sweeps"])
POINT_SETS = list(config["points"])
TILES = {plane: ggrid.tile_ids(config, plane) for plane in PLANES}
AUDIT = float(config["audit"]["fraction"]) > 0


def _alternatives(names):
    return "|".join(names) if names else "^$"


wildcard_constraints:
    plane=_alternatives(PLANES),
    sweep=_alternatives(SWEEPS),
    fig=_alternatives(POINT_SETS),
    tile=r"\d+",


# Software of every gearsim rule (used with --sdm conda).
GEARSIM_ENV = "../envs/gearsim.yaml"

# What the rule files make, by the names the config gives (each rule file names its own outputs;
# a rule reads another file's outputs through an input function, evaluated once every file is
# included, so the files include in any order; `rule all` asks for each file's TARGETS_*).
MULTISTABLE_PLANES = [p for p in PLANES if config["planes"][p].get("multistability")]
ORBIT_TABLES = gcfg.orbit_tables(config)  # config `orbits: {continuation, curves}`
ORBITS_STANDARD = "standard" in ORBIT_TABLES
CURVE_PLANES = [plane for plane in PLANES if f"{plane}_curves" in ORBIT_TABLES]
FIGURE_DATA_TABLES = gfd.figure_data_tables(config)
# the compiled kernels' stamp (rule compile), named by the simulation code's version
KERNEL_STAMP = f"results/.kernels/{CODE_VERSION['tiles']}"
COMPILED = ancient(KERNEL_STAMP)
# jobs that simulate hold one GPU when the study's execution.device is cuda or auto (README, "On
# a GPU"): `--resources gpu=1` runs one at a time; on SLURM the executor asks for it (--gpus=1)
GPU_JOBS = int(STUDY.execution.uses_gpu)


def of_plane(rule_output):
    """An input function: ``rule_output`` (another rule's output pattern) of the job's plane."""
    return lambda wildcards: expand(rule_output(), plane=wildcards.plane)


# ------------------------------------------------------------------------------ helpers
def plane_params(wildcards):
    """The plane's config subtree (+ parameters, integration, tile_rows) as canonical JSON."""
    return gprov.canonical_json(gprov.plane_subtree(STUDY, wildcards.plane))


def planes_params(wildcards):
    """Every plane's config subtree (rule simulate_tiles_together's rerun trigger)."""
    return "".join(gprov.canonical_json(gprov.plane_subtree(STUDY, p)) for p in PLANES)


def audit_params(wildcards):
    return gprov.canonical_json(
        {**gprov.plane_subtree(STUDY, wildcards.plane), "audit": config["audit"]}
    )


def sweep_params(wildcards):
    return gprov.canonical_json(gprov.sweep_subtree(STUDY, wildcards.sweep))


def point_params(wildcards):
    return gprov.canonical_json(gprov.point_subtree(STUDY, wildcards.fig))


def tiles_of_plane(wildcards):
    """Every tile file of the plane ``wildcards.plane`` (rule simulate_tile's outputs)."""
    return expand(
        rules.simulate_tile.output.tile,
        plane=wildcards.plane,
        tile=TILES[wildcards.plane],
    )


def attractors_of_plane(wildcards):
    """Every attractor-tile file of the plane ``wildcards.plane`` (rule attractor_tile's)."""
    return expand(
        rules.attractor_tile.output.attractors,
        plane=wildcards.plane,
        tile=TILES[wildcards.plane],
    )


def figure_data_sweeps(wildcards):
    """The sweep tables the figure-data table ``wildcards.name`` starts from, by name."""
    names = gfd.FIGURE_DATA[wildcards.name].sweeps
    return dict(zip(names, expand(rules.sweep.output.table, sweep=names)))


def table_files():
    """The tables a figure can read: kind -> name -> the file its rule makes (figures.smk)."""
    return {
        "sweeps": dict(zip(SWEEPS, SWEEP_FILES)),
        "planes": dict(zip(PLANES, CELL_FILES)),
        "points": dict(zip(POINT_SETS, POINT_FILES)),
        "orbits": ORBIT_FILES,
        "figure_data": FIGURE_DATA_FILES,
    }


def publish_target():
    """The lab database's (URL, study) of config `publish` (catalogue.smk's publish_server)."""
    from gearsim.errors import USER_ERRORS
    from gearsim.results.server import configured_target

    try:
        return configured_target(config["publish"], config.get("study"))
    except USER_ERRORS as exc:
        print(f"gearsim: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
