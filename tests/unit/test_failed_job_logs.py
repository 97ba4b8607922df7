"""A failed job's log named as a path that opens from where the run was started: Snakemake names
it relative to the folder the run works in (studies/<folder>/ for a study of one's own)."""

from __future__ import annotations

from gearsim.study.preflight import failed_job_logs

# what Snakemake 9 writes for a failed job (snakemake.logging, _format_job_error)
LOG = """\
Building DAG of jobs...
Error in rule simulate_tile:
    jobid: 3
    input: results/.kernels/abc
    output: results/wb/tiles/0.parquet
    log: logs/wb/tile_0.log (check log file(s) for error details)
    shell:
        gearsim simulate-tile --plane wb --tile 0
        (command exited with non-zero exit code)
Error in rule sweep:
    jobid: 5
    log: logs/sweeps/standard.log, /abs/extra.log (check log file(s) for error details)
Shutting down, this might take some time.
"""


def test_failed_logs_are_named_from_the_project_folder(tmp_path):
    log = tmp_path / "run.snakemake.log"
    log.write_text(LOG)
    assert failed_job_logs(log, "small") == [
        "log of the failed job simulate_tile: studies/small/logs/wb/tile_0.log",
        "log of the failed job sweep: studies/small/logs/sweeps/standard.log",
        "log of the failed job sweep: /abs/extra.log",
    ]
    # a run in the project folder: Snakemake's paths are right as they stand
    assert failed_job_logs(log, None) == []
    assert failed_job_logs(tmp_path / "missing.log", "small") == []
    assert failed_job_logs([str(log)], "small") == failed_job_logs(log, "small")  # Snakemake 9
