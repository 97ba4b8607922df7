"""Long-simulation references for single readings of the quick configuration.

Not a timing. For each named record (a plane cell ``PLANE:j:i`` or a sweep point ``SWEEP:k``) the
chain that reaches it is run with this checkout's pipeline (plane rows through
``tiles.simulate_rows_batched``, sweeps through ``study.sweeps.sweep_frame``, the settings of
benchmarks/kernel_identity.py: 256 RK4 steps a period, no tangent lead), and from the state the
chain hands the cell (its left neighbour's final state and period) the cell is simulated again:

* ``rk4``: the pipeline's settings (the chain's own reading, from the cell's start state);
* ``rk4x2``: the same with twice the steps per period (the step's convergence);
* ``dp5``: the audit's reference (``study.audit.audit_settings``: adaptive DP5 at tightened
  tolerances, the configuration's cell plan);
* ``dp5_long``: that DP5 with a transient of ``--long`` periods (default 4 000) before the
  classified window.

Usage: python benchmarks/reading_references.py wxi:3:25 b035:74 [--long 4000]
       python benchmarks/reading_references.py --config config/config.yaml wb:120:300
       python benchmarks/reading_references.py --identity benchmarks/results/kernel_identity.json
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import time

from _common import loadavg, save, setup_env

setup_env()

from gearsim.cell.simulate import chain_start, simulate_cell  # noqa: E402
from gearsim.study import tiles  # noqa: E402
from gearsim.study.audit import audit_settings  # noqa: E402
from gearsim.study.config import Study  # noqa: E402
from gearsim.study.grid import sweep_values  # noqa: E402
from gearsim.study.sweeps import sweep_frame  # noqa: E402

#: benchmarks/kernel_identity.py's settings, so the chain is the one that record compared
OVERRIDES = {"integration": {"tangent_lead": 0, "steps_per_period": 256}}
COLUMNS = ("label", "label_npq", "status", "dc", "kmax", "lyapunov", "periods", "window_periods")


_CHAINS: dict[tuple, object] = {}  # a row's or a sweep's records, computed once


def _row(study: Study, plane: str, j: int) -> dict:
    if (plane, j) not in _CHAINS:
        rows = int(study.config["tile_rows"])
        specs = [s for s in tiles.row_specs(study, plane, j // rows) if s.j == j]
        _CHAINS[plane, j] = {r["i"]: r for r in tiles.simulate_rows_batched(specs)}
    return _CHAINS[plane, j]


def _sweep(study: Study, name: str) -> list[dict]:
    if name not in _CHAINS:
        spec = study.config["sweeps"][name]
        _CHAINS[name] = sweep_frame(
            study.parameters(sweep=name).model, spec["name"], sweep_values(spec),
            spec.get("direction", "forward"), study.settings).to_dict("records")
    return _CHAINS[name]


def _chain(study: Study, key: str):
    """(cell parameters, the chain's record of the cell, its start state and period)."""
    parts = key.split(":")
    if parts[0] in study.config["planes"]:
        plane, j, i = parts[0], int(parts[1]), int(parts[2])
        recs = _row(study, plane, j)
        pl = study.config["planes"][plane]
        base = study.parameters(plane=plane).model
        params = base.with_(**{pl["x"]["name"]: float(recs[i]["x"]),
                               pl["y"]["name"]: float(recs[i]["y"])})
        prev = recs.get(i - 1)
        rec = recs[i]
    else:
        name, k = parts[0], int(parts[1])
        spec = study.config["sweeps"][name]
        base = study.parameters(sweep=name).model
        values = sweep_values(spec)
        recs = _sweep(study, name)
        params = base.with_(**{spec["name"]: float(values[k])})
        prev = recs[k - 1] if k > 0 else None
        rec = recs[k]
    return (params, rec, *chain_start(prev))


def references(study: Study, key: str, long: int) -> dict:
    params, rec, u0, start = _chain(study, key)
    st = study.settings
    runs = {
        "rk4": dict(settings=st),
        "rk4x2": dict(settings=st.with_(steps_per_period=2 * st.steps_per_period)),
        "dp5": dict(settings=audit_settings(study)),
        "dp5_long": dict(settings=audit_settings(study), transient=long),
    }
    out = {"key": key, "chain": {c: rec.get(c) for c in COLUMNS}}
    for name, kw in runs.items():
        t0 = time.process_time()
        row = simulate_cell(params, u0, start_period=start, **kw).row()
        out[name] = {c: row.get(c) for c in COLUMNS} | {"cpu_s": time.process_time() - t0}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", nargs="*", help="PLANE:j:i or SWEEP:k of the configuration")
    ap.add_argument("--identity", metavar="JSON",
                    help="also every record read differently in this kernel_identity.py result "
                         "(its old reading kept beside ours)")
    ap.add_argument("--long", type=int, default=4000, help="dp5_long's transient in periods")
    ap.add_argument("--config", action="append",
                    help="configuration files merged over config/config.yaml (default: "
                         "config/quick.yaml with kernel_identity.py's settings); given, the "
                         "records are those of a run of these files with their own settings")
    args = ap.parse_args(argv)
    if args.config:
        study = Study.load(args.config, root=".")
    else:
        study = Study.load(["config/quick.yaml"], OVERRIDES, root=".")
    load0, res = loadavg(), []
    keys, before = list(args.records), {}
    if args.identity:
        for group in json.load(open(args.identity))["groups"].values():
            for rec, change in group["discrete_examples"]:
                key = ":".join(str(x) for x in ast.literal_eval(rec))
                keys.append(key)
                before[key] = change.get("label", [None])[0]
    for key in keys:
        r = references(study, key, args.long)
        r["before"] = before.get(key)
        res.append(r)
        cells = "  ".join(f"{n} {r[n]['label']} {r[n]['label_npq']} ({r[n]['status']})"
                          for n in ("chain", "rk4", "rk4x2", "dp5", "dp5_long"))
        old = f"before {r['before']}  " if r["before"] else ""
        print(f"{key}: {old}{cells}", flush=True)
    print(save("reading_references", {"records": res, "long": args.long,
                                      "load": [load0, loadavg()]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
