# gearsim workflow: config -> tiles -> cells (Parquet) -> catalogue (SQLite) -> figures, report.
#   snakemake --cores 2                                    # full reproduction (config/config.yaml)
#   snakemake --cores 2 --configfile config/quick.yaml     # a fast look, in studies/quick/
# How to run, outputs and scale-out: docs/pipeline.md.
#
# Every rule names its outputs once; a rule of another file reads them as rules.<name>.output.<key>
# in an input function, so the files include in any order after common.smk (tests/workflow/
# test_rule_order.py); each file names its final products TARGETS_<file>.
from pathlib import Path

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/compile.smk"
include: "workflow/rules/sweeps.smk"
include: "workflow/rules/points.smk"
include: "workflow/rules/planes.smk"
include: "workflow/rules/multistability.smk"
include: "workflow/rules/orbits.smk"
include: "workflow/rules/atlas.smk"
include: "workflow/rules/catalogue.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        TARGETS_SWEEPS,
        TARGETS_POINTS,
        TARGETS_PLANES,
        TARGETS_MULTISTABILITY,
        TARGETS_ORBITS,
        TARGETS_ATLAS,
        TARGETS_CATALOGUE,
        TARGETS_FIGURES,
        TARGETS_REPORT,


onerror:
    # Snakemake names a failed job's log relative to the folder the run works in
    # (studies/<folder>/ for a study of one's own): the same logs as paths from here
    from gearsim.study.preflight import failed_job_logs

    for _line in failed_job_logs(log, RUN_FOLDER):
        print(f"gearsim: {_line}", file=sys.stderr)
