"""The quick configuration's results of an older revision against this checkout's.

Not a timing: an identity check (the quick configuration's catalogue identical in every label,
n, p, q, impact and status; values within 1e-9). The old package is a git revision
(``--rev``) exported with ``git archive`` (``src``, ``config``, ``workflow``); the new one is this
checkout. Each runs in its own interpreter and Numba cache and computes what the quick
configuration's catalogue holds: both planes (every tile, its rows grouped as a tile job with 2
workers groups them, through ``tiles.simulate_rows_batched``), the seven sweeps of both versions'
quick.yaml (``study.sweeps.sweep_frame``) and the three point sets (``study.sweeps.points_frame``).
This checkout's worker asks a :class:`gearsim.study.config.Study` for every parameter set and the
settings; the old revision's worker uses that revision's config functions.
``integration.tangent_lead`` is set to 0 for the new code: the old code had no tangent lead, so
with it on the Lyapunov exponents differ by design. Then every record is compared: the discrete
columns exactly, float columns and arrays (final state, section samples, trajectories) to the
last bit, the largest difference reported.

Usage: python benchmarks/kernel_identity.py --rev REV [--planes-only]
(about 2 x 3 min of CPU on a warm cache; a cold Numba cache adds a compile per version).
"""

from __future__ import annotations

import argparse
import math
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import loadavg, save
from bench_kernel_ab import ROOT, export

DISCRETE = ("label", "n", "p", "q", "impact", "status")
SWEEPS = ("standard", "b015", "b025", "b035", "xi005", "xi009", "xi015")
POINTS = ("fig5", "fig6", "fig9_11")

WORKER = r"""
import argparse, dataclasses, pickle, sys
try:  # the layered package
    from gearsim.study import tiles
    from gearsim.cli.commands import sweep as cmd
    from gearsim.cell.simulate import IntegrationSettings
except ImportError:  # the old revision's flat package
    from gearsim import tiles
    from gearsim.commands import sweep as cmd
    from gearsim.simulate import IntegrationSettings
out, planes_only = sys.argv[1], sys.argv[2] == "1"
fields = {f.name for f in dataclasses.fields(IntegrationSettings)}
# the old code's settings: 256 steps per period (config.yaml has 192)
ov = ({"integration": {"tangent_lead": 0, "steps_per_period": 256}}
      if "tangent_lead" in fields else None)
ap = argparse.ArgumentParser()
cmd.add_arguments(ap)
try:  # this checkout: every parameter through the Study
    from gearsim.study.config import Study
    from gearsim.study.grid import sweep_values
    from gearsim.study.sweeps import points_frame, sweep_frame
except ImportError:  # the old revision: its config functions
    Study = None
    from gearsim.tiles import base_parameters, integration_settings, load_config, sweep_values
    from gearsim.parameters import ModelParameters
if Study is not None:
    study = Study.load(["config/quick.yaml"], ov, root=".")
    cfg, settings = study.config, study.settings
    specs = lambda plane, t: tiles.row_specs(study, plane, t)
    sweep_base = lambda name: study.parameters(sweep=name).model
    def points(fig):
        a = ap.parse_args(["--points", fig])
        return points_frame(study, fig, ramp_from=a.ramp_from, ramp_step=a.ramp_step,
                            periods=a.periods, samples_per_period=a.samples_per_period)
else:
    cfg = load_config(["config/config.yaml", "config/quick.yaml"], ov)
    settings = integration_settings(cfg)
    specs = lambda plane, t: tiles.row_specs(cfg, plane, t)
    def sweep_base(name):
        values, _ = base_parameters(cfg)
        return ModelParameters.from_mapping({**values, **cfg["sweeps"][name].get("fixed", {})})
    sweep_frame = cmd.sweep_frame
    points = lambda fig: cmd.points_frame(cfg, fig, ap.parse_args(["--points", fig]))
res = {}
for plane in ("wb", "wxi"):
    rows = int(cfg["tile_rows"])
    for t in range(-(-int(cfg["planes"][plane]["y"]["n"]) // rows)):
        for g in tiles.row_groups(specs(plane, t), 2):
            for r in tiles.simulate_rows_batched(g):
                res[(plane, r["j"], r["i"])] = r
if not planes_only:
    for name in sys.argv[3].split(","):
        spec = cfg["sweeps"][name]
        df = sweep_frame(sweep_base(name), spec["name"], sweep_values(spec),
                         spec.get("direction", "forward"), settings)
        for k, r in enumerate(df.to_dict("records")):
            res[(name, k)] = r
    for fig in sys.argv[4].split(","):
        for k, r in enumerate(points(fig).to_dict("records")):
            res[(fig, k)] = r
for r in res.values():
    r.pop("elapsed_s", None)
pickle.dump(res, open(out, "wb"))
"""


def run_version(root: Path, cache: Path, out: Path, planes_only: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=str(root / "src"), NUMBA_CACHE_DIR=str(cache),
               NUMBA_NUM_THREADS="1")
    subprocess.run([sys.executable, "-c", WORKER, str(out), "1" if planes_only else "0",
                    ",".join(SWEEPS), ",".join(POINTS)], env=env, cwd=root, check=True)
    with open(out, "rb") as fh:
        return pickle.load(fh)


def _float(v) -> bool:
    return isinstance(v, float) and not isinstance(v, bool)


def compare(old: dict, new: dict) -> dict:
    """Per record group (plane, sweep, point set): discrete mismatches, bit differences."""
    groups: dict[str, dict] = {}
    for key in sorted(set(old) | set(new), key=str):
        g = groups.setdefault(key[0], {"records": 0, "missing": 0, "discrete": 0,
                                       "bit_identical": 0, "max_abs_diff": 0.0,
                                       "discrete_examples": []})
        g["records"] += 1
        if key not in old or key not in new:
            g["missing"] += 1
            continue
        a, b = old[key], new[key]
        bad = [c for c in DISCRETE if c in a and str(a[c]) != str(b.get(c))]
        if bad:
            g["discrete"] += 1
            g["discrete_examples"].append([str(key), {c: (a[c], b.get(c)) for c in bad}])
        same = True
        for c, v in a.items():
            w = b.get(c)
            if _float(v) and _float(w):
                if math.isfinite(v) and math.isfinite(w):
                    d = abs(v - w)
                elif math.isnan(v) and math.isnan(w):
                    d = 0.0
                else:
                    d = math.inf if v != w else 0.0
                same &= d == 0.0
                g["max_abs_diff"] = max(g["max_abs_diff"], d)
            elif isinstance(v, list) and isinstance(w, list):
                if len(v) != len(w):
                    same, d = False, math.inf
                else:
                    d = max((abs(x - y) for x, y in zip(v, w, strict=True)
                             if _float(x) and _float(y)), default=0.0)
                    same &= v == w
                g["max_abs_diff"] = max(g["max_abs_diff"], d)
        g["bit_identical"] += bool(same)
    return groups


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", required=True, help="git revision of the old package")
    ap.add_argument("--planes-only", action="store_true", help="the two planes only")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        old_root = export(args.rev, tmp / "old", ("src", "config", "workflow")).parent
        load0 = loadavg()
        old = run_version(old_root, tmp / "cache_old", tmp / "old.pkl", args.planes_only)
        new = run_version(ROOT, tmp / "cache_new", tmp / "new.pkl", args.planes_only)
    groups = compare(old, new)
    for name, g in groups.items():
        print(f"{name:9s} {g['records']:5d} records: {g['discrete']} with a different "
              f"label/n/p/q/impact/status, {g['bit_identical']} bit-identical, "
              f"max |diff| {g['max_abs_diff']:.3g}, missing {g['missing']}")
    path = save("kernel_identity", {"rev_old": args.rev, "groups": groups,
                                    "load": [load0, loadavg()]})
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
