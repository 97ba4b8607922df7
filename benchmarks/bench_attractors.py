"""(h) Coexisting attractors: the lane-pool finder side by side with the reference finder.

One run measures, on cells of both default planes ((w, b) and (w, xi), the study's settings and
standard parameters, 16 Sobol starts per cell, seed 0):

* ``side by side``: the same cells (each finder in tasks of its pipeline size: 640 cells per
  pool, 64 per reference task) through
  - ``pool``: :func:`gearsim.analysis.attractors.find_attractors` (the pipeline's call: the
    forward-continuation motion of each cell is known from its plane row, no run), certified
    early labels and recurrence; with the share labelled by each rule, the orbits certified
    and their radii, and the lane-periods the certification integrated;
  - ``recurrence``: the same with ``certified=False, newton_seeds=False`` (the recurrence rule
    alone and the forward motion a target only once a start's run reaches it: the rule of the
    finder before certified labels and Newton seeds);
  - ``reference`` (``--reference``): the recurrence mapper
    :func:`gearsim.analysis.attractors.recurrence.map_attractors` on the gear cells (the
    synchronous mapper: scouts, probes, rescouts; the forward state re-run);
  CPU time (process_time), starts per CPU-second, periods per start, share labelled early, and
  the lane use and kernel speed of each, counted identically for both by wrapping the one
  kernel entry (:meth:`gearsim.numerics.batch.Lanes.run`): lane use = lane-periods of lanes
  that take part in a call / lane-periods of every block the call steps; kernel speed =
  lane-steps the kernel computed / CPU time inside it.
* ``agreement`` (``--agree``): every start's label of the pool finder against its full-length
  run (the pool with ``early=False``) on the side-by-side cells (``--near``: every 4th cell
  and every cell next to a change of its row's motion, i.e. a period doubling, fold or
  grazing between two cells of the row; ``--extra-rows K``: the cells next to a change of
  K more rows per plane). Where a start's full-length run is not settled (``unsettled``) and
  its label differs, its own 4 000-period run decides (the label must equal that run's).
* ``scaling``: the pool finder on a sample of rows of both planes at 100, 200 and 400 cells
  per axis (the rows are whole continuation chains; their forward motions come from the
  batched chains, not counted), and the projection of both full planes at 16 starts:
  ``2 n^2 16 / (2 x starts per CPU-second)`` on 2 cores (two tile jobs at a time).

Usage: python benchmarks/bench_attractors.py [--quick] [--agree] [--no-scaling] [--reference]
       [--near] [--extra-rows K] [--repeat R]
"""

from __future__ import annotations

import argparse
import json
import time

from _common import loadavg, save, setup_env

setup_env()

import numpy as np  # noqa: E402

from gearsim.analysis.attractors import (  # noqa: E402
    FinderOptions,
    GearCells,
    find_attractors,
    gear_steady,
    least_periods,
    same_attractor,
    sobol_unit,
)
from gearsim.analysis.attractors.gear import bounded_clouds  # noqa: E402
from gearsim.analysis.attractors.recurrence import map_attractors  # noqa: E402
from gearsim.cell import chains, pool  # noqa: E402
from gearsim.numerics import batch, lanes_layout  # noqa: E402
from gearsim.study.config import Study  # noqa: E402

OPTS = FinderOptions(starts=16, seed=0)
#: the rule of the finder before certified labels and Newton seeds (recurrence alone)
OLD = OPTS.with_(certified=False, newton_seeds=False, neighbour_seeds=False)


def reference(cells, st, states):
    """The recurrence mapper on gear cells (the forward states re-run)."""
    system = GearCells(cells, st)
    opts = OLD.resolved(system.settings.period_rtol)
    unit = sobol_unit(opts.starts, opts.seed)
    found = map_attractors(system, [system.start_states(c, unit) for c in range(len(cells))],
                           opts, continuation=[{"forward": np.asarray(y, dtype=float)[:10]}
                                               for y in states])
    system.fill_margins(found)
    return bounded_clouds(cells, [least_periods(ca, opts.merge_rtol) for ca in found],
                          system.settings)


def long_run(p, y0, st, periods: int = 4000):
    """The steady motion of a 4 000-period run from ``y0`` (transient, then the measuring
    budget), None where it diverges."""
    st = st.with_(transient=periods - st.max_periods,
                  transient_continuation=periods - st.max_periods)
    s = gear_steady(chains.simulate_cells([p], settings=st, u0=[np.asarray(y0)[:10]])[0])
    return None if s.status == "diverged" else s


PLANES = {"wb": ("b", 0.0, 1.0), "wxi": ("xi", 0.04, 0.16)}


def copies(found) -> int:
    """Pairs of periodic attractors of one cell that look like one orbit counted once and k
    times (periods n and k n, k >= 1; same impact state, DC within ORBIT_DC, points within
    ORBIT_RTOL of the range both ways): what the least-period merge must leave none of."""
    from gearsim.analysis.attractors.matching import ORBIT_DC, ORBIT_RTOL, _tolerances, near_all

    out = 0
    for ca in found:
        per = [a.steady for a in ca.attractors if a.steady.status == "ok" and a.steady.period > 0]
        for i, a in enumerate(per):
            for b in per[i + 1:]:
                n, m = sorted((a.period, b.period))
                ia, ib = a.info or {}, b.info or {}
                if m % n or ia.get("I") != ib.get("I"):
                    continue
                da, db = ia.get("dc"), ib.get("dc")
                if da is None or db is None or abs(float(da) - float(db)) > ORBIT_DC:
                    continue
                tx, tv = _tolerances(a, b, ORBIT_RTOL)
                pa, pb = a.points[-a.period:, :2], b.points[-b.period:, :2]
                out += int(near_all(pa, pb, tx, tv) and near_all(pb, pa, tx, tv))
    return out


class KernelMeter:
    """Counts every call of the batched kernel: lane use and lane-steps per CPU-second."""

    def __init__(self):
        self.useful = self.computed = self.steps = 0
        self.cpu = 0.0
        self._run = batch.Lanes.run
        meter = self

        def run(lanes, N, m, nu, bound, tangent=True):
            taking = int(np.sum(lanes.ist[lanes_layout.IST_ST] == 0))
            t0 = time.process_time()
            meter._run(lanes, N, m, nu, bound, tangent)
            meter.cpu += time.process_time() - t0
            meter.useful += taking * m
            meter.computed += lanes.n_blocks * batch.LANES * m
            meter.steps += lanes.n_blocks * batch.LANES * m * N

        batch.Lanes.run = run

    def reset(self):
        self.useful = self.computed = self.steps = 0
        self.cpu = 0.0

    def read(self) -> dict:
        return {"lane_use": self.useful / max(self.computed, 1),
                "kernel_lane_steps_per_cpu_s": self.steps / max(self.cpu, 1e-9),
                "kernel_cpu_s": self.cpu}  # fmt: skip


def row_neighbours(rows) -> list[list[int]]:
    """Per cell: the previous and the next cell of its row (``rows[k]``: row of cell k)."""
    return [[m for m in (k - 1, k + 1) if 0 <= m < len(rows) and rows[m] == rows[k]]
            for k in range(len(rows))]


def rows_of(plane: str, n: int, js, base, st):
    """Cells, forward states and forward motions of rows ``js`` of a plane at n x n."""
    yname, lo, hi = PLANES[plane]
    ws = 0.1 + (np.arange(n) + 0.5) * 2.4 / n
    cells, states, motions = [], [], []
    for j in js:
        y = lo + (j + 0.5) * (hi - lo) / n
        chain = [base.with_(w=float(w), **{yname: float(y)}) for w in ws]
        res = chains.simulate_rows([chain], settings=st)[0]
        cells += chain
        states += [r.final_state for r in res]
        motions += [gear_steady(r) for r in res]
    return cells, states, motions


def _motion_kind(a) -> str:
    """periodic, cloud (chaos, quasi-periodic) or unsettled: what a start's run reached."""
    if a.steady.status != "ok":
        return a.steady.status
    return "periodic" if a.steady.period > 0 else "cloud"


def full_length_by_motion(found, n: int) -> dict:
    """The full-length runs (starts not labelled early) by the motion each reached: starts and
    periods per start of all ``n`` starts (the share of the mean periods per start that each kind
    of run costs)."""
    out: dict[str, dict] = {}
    for ca in found:
        for i in np.flatnonzero(~ca.early.astype(bool)):
            lab = int(ca.start_labels[i])
            kind = "diverged" if lab < 0 else _motion_kind(ca.attractors[lab])
            d = out.setdefault(kind, {"starts": 0, "periods": 0})
            d["starts"] += 1
            d["periods"] += int(ca.start_periods_run[i])
    for d in out.values():
        d["periods_per_start"] = d["periods"] / n
    return out


def summary(found, cpu: float, meter: KernelMeter, stats=None) -> dict:
    n = sum(ca.n_starts for ca in found)
    periods = sum(int(ca.start_periods_run.sum()) for ca in found)
    out = {
        "cells": len(found), "starts": n, "cpu_s": cpu, "starts_per_cpu_s": n / cpu,
        "cpu_per_start_ms": 1e3 * cpu / n, "periods_per_start": periods / n,
        "labelled_early": sum(int(ca.early.sum()) for ca in found) / n, **meter.read(),
        "orbit_copies": copies(found),
    }  # fmt: skip
    P = np.concatenate([ca.start_periods_run for ca in found])
    E = np.concatenate([ca.early for ca in found]).astype(bool)
    out.update({  # where the periods go: early-labelled starts and full-length runs
        "periods_per_early_start": float(P[E].mean()) if E.any() else float("nan"),
        "periods_per_full_start": float(P[~E].mean()) if (~E).any() else float("nan"),
        "full_length_periods_per_start": float(P[~E].sum() / n),
        "full_length_by_motion": full_length_by_motion(found, n),
    })
    if stats is not None:
        radii = [r for r in stats.radii]
        got = np.array([r for r in radii if r is not None], dtype=float)
        out.update({
            "early_certified": stats.early_certified / n,
            "early_recurrence": stats.early_recurrence / n,
            "certify_lane_periods_per_start": stats.certify_periods / n,
            "seeds": {"tried": stats.seeds_tried, "run": stats.seeds_run,
                      "confirmed": stats.seeds_confirmed,
                      "lane_periods_per_start": stats.seed_periods / n},
            "orbits_tried": len(radii), "orbits_certified": int(len(got)),
            "radius_counts": {f"{r:.4g}": int(np.sum(np.isclose(got, r)))
                              for r in sorted(set(got.tolist()), reverse=True)},
        })  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer rows")
    ap.add_argument("--agree", action="store_true", help="also every start's full-length run")
    ap.add_argument("--no-scaling", action="store_true", help="side by side only")
    ap.add_argument("--reference", action="store_true", help="also the recurrence mapper")
    ap.add_argument("--near", action="store_true",
                    help="also every cell next to a change of its row's motion (a doubling, "
                         "fold or grazing between the row's cells)")
    ap.add_argument("--extra-rows", type=int, default=0,
                    help="rows per plane (evenly spaced) of which only the cells next to a "
                         "change of the row's motion join")
    ap.add_argument("--repeat", type=int, default=1,
                    help="side-by-side runs in alternation; each finder's fastest is kept")
    ap.add_argument("--options", default="{}",
                    help="finder options of the pool run (JSON), e.g. '{\"early_clouds\": true}'")
    args = ap.parse_args()
    global OPTS
    OPTS = OPTS.with_(**json.loads(args.options))
    base, st = Study.load().parameters().model, Study.load().settings
    meter = KernelMeter()
    chains.warm_up()
    sobol_unit(4, 0)  # scipy.stats import outside the timings
    out: dict = {"settings": st.to_dict(), "load_before": loadavg()}

    # ---- side by side: every 4th cell of two rows per plane at 400 x 400
    cells, states, motions = [], [], []
    near: list[bool] = []  # the cell is next to a change of the row's motion
    row_of: list[int] = []  # the cells' rows (neighbours: the next cells of a row)
    for plane, js in (("wb", (150, 300)), ("wxi", (100, 250))):
        rows = list(js[:1] if args.quick else js)
        extra = [int(400 * (r + 0.5) / args.extra_rows) for r in range(args.extra_rows)]
        for j in rows + [j for j in extra if j not in rows]:
            only_near = j not in rows
            c, s, m = rows_of(plane, 400, (j,), base, st)
            key = [(x.status, x.period, x.label) for x in m]
            nb = [k > 0 and key[k - 1] != key[k] or k + 1 < len(key) and key[k + 1] != key[k]
                  for k in range(len(key))]  # fmt: skip
            take = [k for k in range(len(c))
                    if (k % 4 == 0 and not only_near) or ((args.near or only_near) and nb[k])]
            cells += [c[k] for k in take]
            states += [s[k] for k in take]
            motions += [m[k] for k in take]
            near += [nb[k] for k in take]
            row_of += [len(set(row_of))] * len(take)
    side = {}
    names = ("pool", "recurrence") + (("reference",) if args.reference else ())
    cpus: dict = {}
    for name in [n for _ in range(max(1, args.repeat)) for n in names]:
        meter.reset()
        c0 = time.process_time()
        # each in tasks of its pipeline size (gearsim attractor-tile: 640 cells per pool
        # task; the reference ran 64 cells per task)
        found = []
        size = 64 if name == "reference" else 640
        stats = None if name == "reference" else pool.PoolStats()
        opts = OLD if name == "recurrence" else OPTS
        for k in range(0, len(cells), size):
            sl = slice(k, k + size)
            if name == "reference":
                found += reference(cells[sl], st, states[sl])
            else:
                found += find_attractors(cells[sl], opts, settings=st,
                                         forward_results=motions[sl], stats=stats,
                                         neighbours=row_neighbours(row_of[sl]))
        row = summary(found, time.process_time() - c0, meter, stats)
        cpus.setdefault(name, []).append(row["cpu_s"])
        if name not in side or row["cpu_s"] < side[name]["cpu_s"]:
            side[name] = row
            side[name]["_found"] = found
        side[name]["cpu_s_runs"] = cpus[name]
    if args.agree:
        meter.reset()
        full = find_attractors(cells, OPTS.with_(early=False), settings=st,
                               forward_results=motions)
        wrong = 0
        differ = []
        early_checked = near_starts = near_early = long_runs = unsettled = 0
        for c, (a, b) in enumerate(zip(side["pool"]["_found"], full, strict=True)):
            la = [a.attractors[k].steady if k >= 0 else None for k in a.start_labels]
            lb = [b.attractors[k].steady if k >= 0 else None for k in b.start_labels]
            early_checked += int(a.early.sum())
            unsettled += sum(1 for y in lb if y is not None and y.status == "unsettled")
            if near[c]:
                near_starts += a.n_starts
                near_early += int(a.early.sum())
            bad = 0
            for i, (x, y) in enumerate(zip(la, lb, strict=True)):
                if (x is None) == (y is None) and (x is None or same_attractor(x, y)):
                    continue
                if y is not None and y.status == "unsettled":
                    long_runs += 1
                    z = long_run(cells[c], a.starts[i], st)
                    if (x is None) == (z is None) and (x is None or same_attractor(x, z)):
                        continue
                bad += 1
            wrong += bad
            if bad:
                differ.append({"w": cells[c].w, "b": cells[c].b, "xi": cells[c].xi,
                               "starts_differing": bad})
        out["agreement"] = {"starts": 16 * len(cells), "labels_differing": wrong,
                            "early_labels_checked": early_checked,
                            "starts_next_to_a_change": near_starts,
                            "early_labels_next_to_a_change": near_early,
                            "unsettled_full_length_runs": unsettled,
                            "unsettled_decided_by_4000_periods": long_runs,
                            "cells_differing": differ}  # fmt: skip
    for v in side.values():
        v.pop("_found")
    out["side_by_side"] = side

    # ---- scaling: rows of both planes at n = 100, 200, 400 (800 cells per size)
    scaling = []
    for n, k in ((100, 4), (200, 2), (400, 1)):
        if args.no_scaling or (args.quick and n > 100):
            break
        js = [int(n * (2 * r + 1) / (2 * k)) for r in range(k)]
        cells, _, motions = [], [], []
        for plane in PLANES:
            c, _s, m = rows_of(plane, n, js, base, st)
            cells += c
            motions += m
        meter.reset()
        c0 = time.process_time()
        stats = pool.PoolStats()
        found = find_attractors(cells, OPTS, settings=st, forward_results=motions,
                                stats=stats)
        row = summary(found, time.process_time() - c0, meter)
        row["n"] = n
        row["rows_per_plane"] = k
        row["projected_both_planes_wall_s_2_cores"] = 2 * n * n * 16 / (2 * row["starts_per_cpu_s"])
        scaling.append(row)
    out["scaling"] = scaling
    out["load_after"] = loadavg()
    path = save("attractors", out)
    print(f"load {out['load_before']} -> {out['load_after']}")
    for name, v in side.items():
        print(f"{name:9s} CPU-s of the runs: {v['cpu_s_runs']}")
        print(f"{name:9s} {v['cells']} cells x 16: {v['starts_per_cpu_s']:.0f} starts/CPU-s "
              f"({v['cpu_per_start_ms']:.2f} ms/start, {v['periods_per_start']:.0f} periods, "
              f"{100 * v['labelled_early']:.0f} % early), lane use {v['lane_use']:.3f}, kernel "
              f"{v['kernel_lane_steps_per_cpu_s'] / 1e6:.1f} M lane-steps/CPU-s, "
              f"{v['orbit_copies']} pairs of one orbit in a cell; early starts "
              f"{v['periods_per_early_start']:.1f} periods, full-length "
              f"{v['periods_per_full_start']:.0f} ({v['full_length_periods_per_start']:.1f} per "
              f"start)")
        print(f"{name:9s} full-length runs by the motion reached: " + "; ".join(
            f"{k} {d['starts']} starts, {d['periods_per_start']:.1f} periods per start"
            for k, d in sorted(v["full_length_by_motion"].items())))
    for name, v in side.items():
        if "radius_counts" in v:
            print(f"{name:9s} early: {100 * v['early_certified']:.0f} % certified, "
                  f"{100 * v['early_recurrence']:.0f} % by recurrence (counted at the chunk "
                  f"checks); {v['orbits_certified']}/{v['orbits_tried']} orbits certified, "
                  f"radii {v['radius_counts']}, certification "
                  f"{v['certify_lane_periods_per_start']:.1f} lane-periods per start; seeds from "
                  f"the neighbours {v['seeds']}")
    if "agreement" in out:
        a = out["agreement"]
        print(f"agreement with full-length runs: {a['starts'] - a['labels_differing']}/"
              f"{a['starts']} starts ({a['early_labels_checked']} early labels; "
              f"{a['starts_next_to_a_change']} starts, {a['early_labels_next_to_a_change']} "
              f"early, in cells next to a change of the row's motion; "
              f"{a['unsettled_full_length_runs']} full-length runs unsettled, "
              f"{a['unsettled_decided_by_4000_periods']} of them with another label decided by "
              f"4 000 periods); cells differing: "
              f"{a['cells_differing']}")
    for r in scaling:
        print(f"n = {r['n']}: {r['cells']} cells, {r['starts_per_cpu_s']:.0f} starts/CPU-s, lane "
              f"use {r['lane_use']:.3f}, kernel {r['kernel_lane_steps_per_cpu_s'] / 1e6:.1f} M "
              f"lane-steps/CPU-s; both {r['n']}^2 planes: "
              f"{r['projected_both_planes_wall_s_2_cores'] / 60:.1f} min on 2 cores")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
