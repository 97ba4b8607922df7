"""The growth rule (cell/growth.py) on a run's plane tiles: which cells it checks, what it costs,
which labels it changes.

Every chaotic or quasi-periodic cell of the tiles (``results/<plane>/tiles/*.parquet`` of a run
made without the rule, or with it: then nothing changes) goes through
:func:`gearsim.cell.growth.check_growth` from its stored window end (the state its chain went
on from), exactly the tail the drivers now add. Printed per plane: cells, cells without a
period, their ``mu_lin`` CPU seconds, cells at ``mu_lin > 1``, long runs (periods, CPU
seconds) and, with ``--logs``, the tile stage's CPU seconds (the snakemake benchmark files
``<logs>/benchmarks/<plane>/tile_*.tsv``) and the rule's share of them; then one line per cell
whose label changes. ``--csv`` writes those cells.

Usage:
    python benchmarks/bench_growth.py --results results --logs logs [--csv changes.csv]
"""

from __future__ import annotations

import argparse
import glob
import json
import time
from dataclasses import fields

import numpy as np
import pandas as pd

from gearsim.cell.classify import Classification
from gearsim.cell.growth import CHECKED, check_growth, linear_multipliers
from gearsim.cell.simulate import CellResult
from gearsim.study.config import Study


def _result(row: pd.Series, params) -> CellResult:
    """The tile row as the :class:`CellResult` its driver held before the rule."""
    vals = {f.name: row[f.name] for f in fields(Classification) if f.name in row.index}
    vals.update(I=int(row["I"]), n=int(row["n"]), mu_lin=float("nan"), long_run=float("nan"))
    return CellResult(Classification(**vals), np.asarray(row["final_state"], dtype=float),
                      int(row["final_period"]), np.zeros((0, 10)), int(row["periods"]),
                      int(row["steps"]), params)  # fmt: skip


def _tile_cpu(logs: str | None, plane: str) -> float | None:
    if not logs:
        return None
    fs = sorted(glob.glob(f"{logs}/benchmarks/{plane}/tile_*.tsv"))
    return sum(float(pd.read_csv(f, sep="\t")["cpu_time"].iloc[-1]) for f in fs) if fs else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", required=True, help="a run's results folder")
    ap.add_argument("--logs", help="the run's logs folder (tile stage CPU seconds)")
    ap.add_argument("--configfile", nargs="*", default=["config/config.yaml"])
    ap.add_argument("--csv", help="write the cells whose label changes here")
    args = ap.parse_args()
    study = Study.load(args.configfile)
    st = study.settings
    changes = []
    for plane, pl in study.config["planes"].items():
        fs = sorted(glob.glob(f"{args.results}/{plane}/tiles/*.parquet"))
        if not fs:
            continue
        df = pd.concat([pd.read_parquet(f) for f in fs], ignore_index=True)
        xname, yname = pl["x"]["name"], pl["y"]["name"]
        base = study.parameters(plane=plane).model
        cand = df[df["motion"].isin(CHECKED)]
        params = [base.with_(**{xname: float(r[xname]), yname: float(r[yname])})
                  for _, r in cand.iterrows()]  # fmt: skip
        t0 = time.process_time()
        mus = linear_multipliers(params, st) if params else np.zeros(0)
        cpu_mu = time.process_time() - t0
        todo = [(r, _result(r, p)) for (_, r), p, mu in zip(cand.iterrows(), params, mus,
                                                            strict=True) if mu > 1.0]
        t0 = time.process_time()
        check_growth([cr for _, cr in todo], st)
        cpu_long = time.process_time() - t0
        tile = _tile_cpu(args.logs, plane)
        print(json.dumps({
            "plane": plane, "cells": len(df), "without_period": len(cand),
            "cpu_mu_lin": round(cpu_mu, 3), "mu_lin_above_1": len(todo),
            "long_run_periods": float(sum(cr.classification.long_run for _, cr in todo)),
            "cpu_long_runs": round(cpu_long, 3), "tile_stage_cpu": tile,
            "share": None if not tile else round((cpu_mu + cpu_long) / tile, 5)}))
        for r, cr in todo:
            c = cr.classification
            if c.label != r["label"]:
                changes.append({"plane": plane, "i": int(r["i"]), "j": int(r["j"]),
                                xname: float(r[xname]), yname: float(r[yname]),
                                "old": r["label"], "new": c.label, "kmax": float(r["kmax"]),
                                "mu_lin": c.mu_lin, "long_run": c.long_run})  # fmt: skip
    for ch in changes:
        print(json.dumps(ch))
    if args.csv:
        pd.DataFrame(changes).to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
