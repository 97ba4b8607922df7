"""One point of ``gearsim point``: simulated from rest, its table row (the physical columns
with a gear file, the tightened re-run with ``check``, the Lyapunov spectrum), the lines the
command prints and the file of its time series (``--out``)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION, KMAX_READINGS
from gearsim.cell.simulate import simulate_cell, trajectory
from gearsim.errors import UsageError
from gearsim.study.config import settings_text


def strict_json(row: dict) -> dict:
    """NaN and infinities -> null, numpy scalars -> Python numbers (strict JSON)."""
    out: dict[str, Any] = {}
    for k, v in row.items():
        if isinstance(v, np.floating | float):
            v = float(v)
            out[k] = v if math.isfinite(v) else None
        elif isinstance(v, np.integer):
            out[k] = int(v)
        elif isinstance(v, np.bool_):
            out[k] = bool(v)
        elif isinstance(v, dict):
            out[k] = strict_json(v)
        else:
            out[k] = v
    return out


def simulate_point(params, settings, *, source: str, spectrum=False, check: bool = False,
                   gear=None):
    """``(result, row, seconds)`` of the point: the cell's row with ``w``, the wall time, the
    parameters' source and the settings (and the physical columns, the tightened label, the
    spectrum where asked)."""
    t0 = time.perf_counter()
    res = simulate_cell(params, settings=settings, spectrum=spectrum)
    elapsed = time.perf_counter() - t0
    c = res.classification
    row = res.row()
    row.update(w=params.w, elapsed_s=elapsed, parameters_source=source,
               settings=settings.to_dict())
    if gear is not None:
        from gearsim.physical.units import physical_columns

        row = physical_columns(row, gear, params)
    if check:
        tight = simulate_cell(params, settings=settings.tightened()).classification
        row["tight_label"] = tight.label
        row["tight_npq"] = tight.label_npq
        row["classification_stable"] = tight.label == c.label and tight.label_npq == c.label_npq
    if res.spectrum is not None:
        row["spectrum"] = [float(v) for v in res.spectrum.exponents]
        row["spectrum_sum"] = float(res.spectrum.exponents.sum())
        row["spectrum_trace"] = res.spectrum.trace
        row["spectrum_ok"] = res.spectrum.ok()
    return res, row, elapsed


def _num(v: float, spec: str) -> str:
    """A reading as printed: ``none`` where the row has none (NaN: a motion that never
    settled)."""
    return format(v, spec) if v == v else "none"


def summary_lines(params, res, row: dict, *, source: str, settings, elapsed: float,
                  gear=None, gear_path: str = "") -> list[str]:
    """What ``gearsim point`` prints: the parameters' source and settings, the motion and its
    readings (the row's: none for a motion that never settled, its status saying why), Kmax's
    definition beside the other readings, the spectrum and the physical line where present."""
    c = res.classification
    pattern = f"{c.label} ({c.label_npq})" if c.label_npq else c.label
    line = (
        f"w={params.w:.4f} pattern={pattern} I={c.I} DC={_num(row['dc'], '.4f')} "
        f"Kmax={_num(row['kmax'], '.4f')} lyapunov={_num(row['lyapunov'], '+.4f')} "
        f"status={c.status} converged={c.converged} periods={res.periods} "
        f"({elapsed * 1e3:.0f} ms)"
    )
    if "tight_label" in row:
        line += f" tight={row['tight_label']} stable={row['classification_stable']}"
    others = " ".join(f"{k}={_num(row[k], '.4f')}" for k in KMAX_READINGS if k != DEFAULT_KMAX)
    lines = [f"parameters: {source}; integration: {settings_text(settings)}", line,
             f"Kmax = {KMAX_DEFINITION}; other readings: {others}"]
    if res.spectrum is not None:
        sp = res.spectrum
        lines.append("spectrum (per unit tau): " + " ".join(f"{v:+.5f}" for v in sp.exponents)
                     + f"  sum={sp.exponents.sum():+.5f} trace={sp.trace:+.5f} "
                     + ("ok" if sp.ok() else "SUM DOES NOT MATCH THE TRACE"))
    if gear is not None:
        from gearsim.physical.units import physical_line

        lines.append(physical_line(row, gear_path))
    return lines


def save(path: Path, params, res, settings, source: str) -> Path:
    """Time series, Poincare points and spectrum of the steady motion to a Parquet file, with
    the parameters, their source, the settings and the classification row in its metadata."""
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
            b"gearsim.classification": json.dumps(strict_json(res.row())).encode()}
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    try:
        pq.write_table(table, path)
    except OSError as exc:
        raise UsageError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path
