"""``gearsim sweep``: a one-parameter sweep (bifurcation data) or a figure's named points."""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
from typing import Any

import numpy as np
import pandas as pd

from gearsim.cell.simulate import simulate_cell, trajectory
from gearsim.cell.sweep import continuation_chain, sweep_records
from gearsim.cli.commands._common import add_parameter_arguments, check_new_file, resolve_parameters
from gearsim.cli.commands.simulate_tile import Progress
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError
from gearsim.results import catalogue
from gearsim.study.config import (
    base_parameters,
    integration_settings,
    resolved_parameters,
    results_dir,
)
from gearsim.study.grid import sweep_values
from gearsim.study.provenance import provenance, sweep_subtree
from gearsim.study.tiles import records_to_frame

NAME = "sweep"
HELP = "run a configured sweep (--name) or figure point set (--points) and write its Parquet file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--name", help="sweep name (a key of `sweeps:`)")
    what.add_argument("--points", metavar="FIG", help="point set name (a key of `points:`)")
    add_parameter_arguments(p, integration=False)
    p.add_argument(
        "--out",
        "-o",
        default=None,
        help="output Parquet file (default <results>/sweeps/<name>.parquet or "
        "<results>/points/<set>.parquet)",
    )
    p.add_argument(
        "--ramp-from",
        type=float,
        default=0.1,
        help="points: start of the forward continuation ramp in w",
    )
    p.add_argument("--ramp-step", type=float, default=0.02, help="points: ramp step in w")
    p.add_argument("--periods", type=int, default=64, help="points: recorded mesh periods")
    p.add_argument(
        "--samples-per-period",
        type=int,
        default=128,
        help="points: recorded samples per mesh period",
    )


def sweep_frame(
    base, name: str, values: np.ndarray, direction: str, settings, progress=None,
    start: str = "continuation",
) -> pd.DataFrame:
    """The records of :func:`gearsim.cell.sweep.sweep_records` with the catalogue's stable dtypes.

    ``start="rest"``: every cell from the static state instead of the previous cell's state.
    """
    return records_to_frame(sweep_records(base, name, values, direction=direction,
                                          settings=settings, progress=progress,
                                          continuation=start == "continuation"))


def _point_list(spec) -> list[dict[str, float]]:
    if isinstance(spec, list):
        return [{"w": float(w)} for w in spec]
    keys = list(spec)
    lists = [v if isinstance(v, list) else [v] for v in spec.values()]
    return [dict(zip(keys, map(float, combo), strict=True)) for combo in itertools.product(*lists)]


def points_frame(config, fig: str, args, progress=None) -> pd.DataFrame:
    """Each point twice: reached by a forward ramp in w (as in the sweeps) and from rest."""
    values, _ = base_parameters(config)
    settings = integration_settings(config)
    points = _point_list(config["points"][fig])
    for pt in points:
        if "w" not in pt:
            raise UsageError(f"points.{fig}: every point needs a value of w")
    rows: list[dict[str, Any]] = []
    groups: dict[tuple, list[int]] = {}
    for k, pt in enumerate(points):
        groups.setdefault(tuple(sorted((n, v) for n, v in pt.items() if n != "w")), []).append(k)
    done = 0
    t0 = time.perf_counter()
    for other, idx in groups.items():
        base = ModelParameters.from_mapping({**values, **dict(other)})
        targets = sorted({points[k]["w"] for k in idx})
        ramp = np.arange(args.ramp_from, max(targets), args.ramp_step)
        ws = sorted(set(np.round(ramp, 12).tolist()) | set(targets))
        chain = continuation_chain([base.with_(w=float(w)) for w in ws], settings=settings)
        at = {w: r for w, r in zip(ws, chain, strict=True)}
        for k in idx:
            pt = points[k]
            params = base.with_(w=pt["w"])
            for start, res in (
                ("continuation", at[pt["w"]]),
                ("rest", simulate_cell(params, settings=settings)),
            ):
                tr = trajectory(
                    params,
                    res.final_state,
                    periods=args.periods,
                    samples_per_period=args.samples_per_period,
                    settings=settings,
                    start_period=res.final_period,
                )
                row = {"figure": fig, "point": k, "start": start, **pt}
                row.update(res.row())
                row["poincare_x"] = res.poincare[:, 0].tolist()
                row["poincare_v"] = res.poincare[:, 1].tolist()
                row["tau"] = tr.tau.tolist()
                row["x"] = tr.state[:, 0].tolist()
                row["xdot"] = tr.state[:, 1].tolist()
                row["mesh_force"] = tr.mesh_force.tolist()
                row["section_x"] = tr.section[:, 0].tolist()
                row["section_v"] = tr.section[:, 1].tolist()
                row["final_state"] = res.final_state.tolist()
                rows.append(row)
            done += 1
            if progress:
                progress(done, len(points), time.perf_counter() - t0)
    return records_to_frame(rows)


def _check_recording(args: argparse.Namespace) -> None:
    checks = (
        ("--ramp-from", args.ramp_from, 0.0, 100.0, False),
        ("--ramp-step", args.ramp_step, 0.0, 10.0, False),
        ("--periods", args.periods, 1, 100_000, True),
        ("--samples-per-period", args.samples_per_period, 4, 100_000, True),
    )
    for flag, v, lo, hi, closed in checks:
        ok = math.isfinite(v) and (lo <= v if closed else lo < v) and v <= hi
        if not ok:
            rng = f"[{lo}, {hi}]" if closed else f"({lo}, {hi}]"
            raise UsageError(f"{flag}: {v!r} is outside {rng}")


def resolve(args: argparse.Namespace):
    """The sweep's base parameters: the shared resolution (the swept value and the sweep's
    ``fixed`` values are set per point); its ``config`` carries them into the provenance."""
    return resolve_parameters(args)


def run(args: argparse.Namespace) -> int:
    _check_recording(args)
    config = resolve(args).config
    res = results_dir(config)
    default = (
        res / "sweeps" / f"{args.name}.parquet"
        if args.name
        else res / "points" / f"{args.points}.parquet"
    )
    out = check_new_file(args.out or default)
    started = catalogue.now_iso()
    t0 = time.perf_counter()
    if args.name:
        if args.name not in config["sweeps"]:
            raise UsageError(
                f"unknown sweep '{args.name}'; configured: {', '.join(config['sweeps']) or 'none'}"
            )
        spec = config["sweeps"][args.name]
        values, _ = base_parameters(config)
        base = ModelParameters.from_mapping({**values, **spec.get("fixed", {})})
        vals = sweep_values(spec)
        progress = Progress(f"sweep {args.name}", len(vals))
        df = sweep_frame(
            base,
            spec["name"],
            vals,
            spec.get("direction", "forward"),
            integration_settings(config),
            progress,
            spec.get("start", "continuation"),
        )
        subtree = sweep_subtree(config, args.name)
        kind, name = "sweep", args.name
    else:
        if args.points not in config["points"]:
            raise UsageError(
                f"unknown point set '{args.points}'; configured: "
                f"{', '.join(config['points']) or 'none'}"
            )
        progress = Progress(
            f"points {args.points}", len(_point_list(config["points"][args.points]))
        )
        df = points_frame(config, args.points, args, progress)
        subtree = {
            "points": config["points"][args.points],
            "parameters": resolved_parameters(config),
            "integration": integration_settings(config).to_dict(),
            "recording": {
                "ramp_from": args.ramp_from,
                "ramp_step": args.ramp_step,
                "periods": args.periods,
                "samples_per_period": args.samples_per_period,
            },
        }
        kind, name = "points", args.points
    progress.close()
    wall = time.perf_counter() - t0
    prov = provenance(
        subtree,
        kind=kind,
        name=name,
        config=config,
        started=started,
        finished=catalogue.now_iso(),
        wall_s=wall,
        cells=len(df),
        workers="in-process",
    )
    catalogue.write_parquet(df, out, {catalogue.PROVENANCE_KEY: prov})
    print(f"{kind} {name}: wrote {out} ({len(df)} rows in {wall:.1f} s)", file=sys.stderr)
    return 0
