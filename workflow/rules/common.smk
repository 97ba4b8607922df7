# Config validation, tile list, shared helpers. Everything here runs once when the workflow is
# parsed, before any job starts.
import hashlib
import json

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from gearsim import config as gcfg
from gearsim import grid as ggrid
from gearsim import provenance as gprov

SCHEMA = Path(workflow.basedir) / "workflow/schemas/config.schema.yaml"

# 1. One clear line naming the bad key (the same check as the gearsim CLI), then Snakemake's
#    validate(), which fills the schema defaults.
try:
    gcfg.validate_schema(config, gcfg.load_schema(workflow.basedir))
    gcfg.check_config(config)
except gcfg.ConfigError as exc:
    raise WorkflowError(f"invalid configuration: {exc}") from None
validate(config, str(SCHEMA))

# 2. How the CLI sees the same config: the config files in Snakemake's merge order, then the
#    `--config` overrides (saved to a content-addressed file). Rules take them as ancient()
#    inputs: the CLI reads them, but editing one plane in config.yaml must not re-run every job
#    (the params below decide what re-runs).

_cli_files = [str(f) for f in workflow.config_settings.configfiles]
_own_files = [str(f) for f in workflow.configfiles if str(f) not in _cli_files]
if getattr(workflow.config_settings, "replace_workflow_config", False):
    _own_files = []
CONFIG_FILES = _own_files + _cli_files
if workflow.config_settings.config:
    _ovr = json.dumps(workflow.config_settings.config, sort_keys=True)
    _digest = hashlib.sha256(_ovr.encode()).hexdigest()[:16]
    _ovr_file = Path(".snakemake/gearsim", f"overrides-{_digest}.json")
    if not _ovr_file.exists():
        _ovr_file.parent.mkdir(parents=True, exist_ok=True)
        _ovr_file.write_text(_ovr)
    CONFIG_FILES.append(str(_ovr_file))
CONFIG = ancient(CONFIG_FILES)

# 3. What the jobs depend on. code_version hashes every module that decides results
#    (gearsim.provenance.code_files): Snakemake does not see edits to a package.
CODE_VERSION = gprov.code_version()
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

# Final products; each included .smk extends this list, and `rule all` asks for it.
ALL_TARGETS = []


# ------------------------------------------------------------------------------ helpers
def plane_params(wildcards):
    """The plane's config subtree (+ parameters, integration, tile_rows) as canonical JSON."""
    return gprov.canonical_json(gprov.plane_subtree(config, wildcards.plane))


def audit_params(wildcards):
    return gprov.canonical_json(
        {**gprov.plane_subtree(config, wildcards.plane), "audit": config["audit"]}
    )


def sweep_params(wildcards):
    return gprov.canonical_json(gprov.sweep_subtree(config, wildcards.sweep))


def point_params(wildcards):
    return gprov.canonical_json(
        {
            "points": config["points"][wildcards.fig],
            "parameters": gcfg.resolved_parameters(config),
            "integration": gcfg.integration_settings(config).to_dict(),
        }
    )


def tiles_of_plane(wildcards):
    return expand(
        "results/{plane}/tiles/{tile}.parquet",
        plane=wildcards.plane,
        tile=TILES[wildcards.plane],
    )


# The compile stamp orders jobs without making every tile out of date when it is rewritten
# (a code change re-runs them through the code_version param instead).
COMPILED = ancient("results/.compiled")
