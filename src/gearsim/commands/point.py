"""``gearsim point``: simulate and classify one parameter point."""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from ..simulate import simulate_cell, trajectory
from ._common import add_parameter_arguments, parameters_from_args, settings_from_args
from .gear import add_gear_arguments, point_parameters

NAME = "point"
HELP = "simulate one point and print its pattern, DC, Kmax, Lyapunov exponent and convergence"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--omega", "-w", type=float, default=None,
        help="dimensionless mesh frequency w (required unless --gear with --rpm)",
    )
    add_parameter_arguments(p)
    add_gear_arguments(p)
    p.add_argument("--save", metavar="PARQUET", help="write time series, Poincare points, spectrum")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument(
        "--check", action="store_true", help="re-run at tightened tolerance and compare"
    )


def run(args: argparse.Namespace) -> int:
    params, gear = point_parameters(args, parameters_from_args)
    settings = settings_from_args(args)
    t0 = time.perf_counter()
    res = simulate_cell(params, settings=settings)
    elapsed = time.perf_counter() - t0
    c = res.classification
    row = res.row()
    row.update(w=params.w, elapsed_s=elapsed)
    if gear is not None:
        from ..units import physical_columns

        row = physical_columns(row, gear, params)
    if args.check:
        tight = simulate_cell(params, settings=settings.tightened()).classification
        row["tight_label"] = tight.label
        row["tight_npq"] = tight.label_npq
        row["classification_stable"] = tight.label == c.label and tight.label_npq == c.label_npq
    if args.json:
        print(json.dumps(row, default=float))
    else:
        pattern = f"{c.label} ({c.label_npq})" if c.label_npq else c.label
        line = (
            f"w={params.w:.4f} pattern={pattern} I={c.I} DC={c.dc:.4f} "
            f"Kmax={c.kmax:.4f} [peak/Fm={c.kmax_peak_mean:.3f} sec/(Fm+Few2)="
            f"{c.kmax_section_static:.3f}] lyapunov={c.lyapunov:+.4f} status={c.status} "
            f"converged={c.converged} periods={res.periods} ({elapsed * 1e3:.0f} ms)"
        )
        if args.check:
            line += f" tight={row['tight_label']} stable={row['classification_stable']}"
        print(line)
        if gear is not None:
            from ..units import physical_line

            print(physical_line(row, args.gear))
    if args.save:
        _save(args.save, params, res, settings)
    return 0


def _save(path: str, params, res, settings) -> None:
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    periods = max(64, 4 * max(res.classification.n, 1))
    spp = 128
    tr = trajectory(
        params, res.final_state, periods=periods, samples_per_period=spp, settings=settings,
        start_period=res.final_period,
    )
    x = tr.state[:-1, 0]
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(len(x)))) / len(x)
    dtau = params.mesh_period / spp
    freq = 2 * np.pi * np.fft.rfftfreq(len(x), d=dtau)  # angular, units of w_n
    ts = pd.DataFrame({"tau": tr.tau, "x": tr.state[:, 0], "xdot": tr.state[:, 1],
                       "mesh_force": tr.mesh_force})
    table = pa.table({
        "kind": ["time_series"] * len(ts)
        + ["poincare"] * len(tr.section)
        + ["spectrum"] * len(freq),
        "tau": np.concatenate([ts.tau, np.arange(len(tr.section)) * params.mesh_period, freq * 0]),
        "x": np.concatenate([ts.x, tr.section[:, 0], np.zeros(len(freq))]),
        "xdot": np.concatenate([ts.xdot, tr.section[:, 1], np.zeros(len(freq))]),
        "mesh_force": np.concatenate([ts.mesh_force, np.zeros(len(tr.section) + len(freq))]),
        "frequency": np.concatenate([np.zeros(len(ts) + len(tr.section)), freq]),
        "amplitude": np.concatenate([np.zeros(len(ts) + len(tr.section)), spec]),
    })
    meta = {b"gearsim.params": json.dumps(params.to_dict()).encode(),
            b"gearsim.classification": json.dumps(res.row(), default=float).encode()}
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    pq.write_table(table, path)
    print(f"saved {path}")
