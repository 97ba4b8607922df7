"""``gearsim point``: simulate and classify one parameter point."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION, KMAX_READINGS
from gearsim.cell.simulate import simulate_cell, trajectory
from gearsim.cli.commands._common import (
    add_device_argument,
    add_parameter_arguments,
    check_output_path,
    command_parameters,
    json_safe,
    select_device,
    settings_from_args,
)
from gearsim.errors import UsageError
from gearsim.study.config import settings_text

NAME = "point"
HELP = "simulate one point and print its pattern, DC, Kmax, Lyapunov exponent and convergence"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--omega", "-w", type=float, default=None,
        help="dimensionless mesh frequency w (default with --gear: the gear file's speed_rpm; "
        "otherwise required unless --set w=... or the study's parameters give it)",
    )
    add_parameter_arguments(p)
    add_device_argument(p)
    p.add_argument(
        "--out",
        "-o",
        "--save",
        dest="out",
        metavar="PARQUET",
        help="write time series, Poincare points and spectrum to this Parquet file "
        "(--save is the old spelling)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the result as one JSON object (no NaN)"
    )
    p.add_argument(
        "--check", action="store_true", help="re-run at tightened tolerance and compare"
    )
    p.add_argument(
        "--spectrum", nargs="?", type=int, const=0, default=None, metavar="PERIODS",
        help="also compute all Lyapunov exponents (QR of a tangent basis) over PERIODS mesh "
        "periods (default: max(200, analysed window)); the sum is checked against the trace",
    )


def resolve(args: argparse.Namespace):
    """The point's parameters (:func:`gearsim.cli.commands._common.command_parameters`): a gear
    file gives its own speed and torque (``speed_rpm``, ``torque_Nm``) unless an option sets
    them, so ``--omega`` is required only without one."""
    return command_parameters(args, omega_required=not args.gear, w=args.omega)


def run(args: argparse.Namespace) -> int:
    out = check_output_path(args.out) if args.out else None
    r = resolve(args)
    select_device(args, r.study)  # a device that cannot run is one line; one cell runs here
    params, source, gear = r.params, r.source, r.gear
    settings = settings_from_args(args, r.study)
    t0 = time.perf_counter()
    spectrum = False if args.spectrum is None else (args.spectrum or True)
    res = simulate_cell(params, settings=settings, spectrum=spectrum)
    elapsed = time.perf_counter() - t0
    c = res.classification
    row = res.row()
    row.update(w=params.w, elapsed_s=elapsed, parameters_source=source,
               settings=settings.to_dict())
    if gear is not None:
        from gearsim.physical.units import physical_columns

        row = physical_columns(row, gear, params)
    if args.check:
        tight = simulate_cell(params, settings=settings.tightened()).classification
        row["tight_label"] = tight.label
        row["tight_npq"] = tight.label_npq
        row["classification_stable"] = tight.label == c.label and tight.label_npq == c.label_npq
    if res.spectrum is not None:
        row["spectrum"] = [float(v) for v in res.spectrum.exponents]
        row["spectrum_sum"] = float(res.spectrum.exponents.sum())
        row["spectrum_trace"] = res.spectrum.trace
        row["spectrum_ok"] = res.spectrum.ok()
    if args.json:
        print(json.dumps(json_safe(row), allow_nan=False))
    else:
        print(f"parameters: {source}; integration: {settings_text(settings)}")
        pattern = f"{c.label} ({c.label_npq})" if c.label_npq else c.label
        line = (
            f"w={params.w:.4f} pattern={pattern} I={c.I} DC={c.dc:.4f} "
            f"Kmax={c.kmax:.4f} lyapunov={c.lyapunov:+.4f} status={c.status} "
            f"converged={c.converged} periods={res.periods} ({elapsed * 1e3:.0f} ms)"
        )
        if args.check:
            line += f" tight={row['tight_label']} stable={row['classification_stable']}"
        print(line)
        # Kmax's definition, and the other readings under their own names (docs/model.md)
        others = " ".join(f"{k}={getattr(c, k):.4f}" for k in KMAX_READINGS if k != DEFAULT_KMAX)
        print(f"Kmax = {KMAX_DEFINITION}; other readings: {others}")
        if res.spectrum is not None:
            sp = res.spectrum
            print("spectrum (per unit tau): " + " ".join(f"{v:+.5f}" for v in sp.exponents)
                  + f"  sum={sp.exponents.sum():+.5f} trace={sp.trace:+.5f} "
                  + ("ok" if sp.ok() else "SUM DOES NOT MATCH THE TRACE"))
        if gear is not None:
            from gearsim.physical.units import physical_line

            print(physical_line(row, r.gear_path or ""))
    if out is not None:
        _save(out, params, res, settings, source)
    return 0


def _save(path: Path, params, res, settings, source: str) -> None:
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
            b"gearsim.parameters_source": source.encode(),
            b"gearsim.settings": json.dumps(settings.to_dict()).encode(),
            b"gearsim.classification": json.dumps(json_safe(res.row())).encode()}
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    try:
        pq.write_table(table, path)
    except OSError as exc:
        raise UsageError(f"{path}: cannot write ({exc.strerror or exc})") from None
    print(f"saved {path}")
