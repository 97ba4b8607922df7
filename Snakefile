# gearsim workflow: config -> tiles -> cells (Parquet) -> catalogue (SQLite) -> figures, report.
#   snakemake --cores 2                                    # full reproduction (config/config.yaml)
#   snakemake --cores 2 --configfile config/quick.yaml     # a fast look
# How to run, outputs and scale-out: docs/pipeline.md.
from pathlib import Path

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/sweeps.smk"
include: "workflow/rules/points.smk"
include: "workflow/rules/multistability.smk"
include: "workflow/rules/planes.smk"


# Stages owned by other engineers extend ALL_TARGETS when their files exist.
if Path(workflow.basedir, "workflow/rules/figures.smk").exists():

    include: "workflow/rules/figures.smk"


if Path(workflow.basedir, "workflow/rules/orbits.smk").exists():

    include: "workflow/rules/orbits.smk"


if Path(workflow.basedir, "workflow/rules/report.smk").exists():

    include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        ALL_TARGETS,
