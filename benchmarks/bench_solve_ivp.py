"""(c) The same cells through scipy.integrate.solve_ivp (RK45, rtol 1e-8, atol 1e-10) with events.

The 6-DOF equations with *true* dead zones (no frozen regions) and the variational equations
(20 states during the measurement, 10 in the transient) are integrated one mesh period per
``solve_ivp`` call (the section lands exactly on the period boundary; the tangent vector is
renormalised there). Contact changes are located by scipy's event root finder on
``x - b`` and ``x + b`` (non-terminal, with directions: face entries are upward crossings of
``x = b``, back entries downward crossings of ``x = -b``); the time inside the backlash comes
from the ordered crossing times; force and displacement extremes from the dense output
(64 samples per period). The early-stopping logic of simulate_cell (transient, chunks, period
test, classify_motion) is applied to these per-period summaries, so the two paths are compared
at equal classification: labels must agree, then the CPU-time ratio per cell is reported.

Usage: python benchmarks/bench_solve_ivp.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import sys
import time

from _common import loadavg, save, setup_env

setup_env()

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from gearsim.cell import chains  # noqa: E402
from gearsim.cell.classify import classify_motion, estimate_period  # noqa: E402
from gearsim.cell.simulate import IntegrationSettings, initial_tangent, simulate_cell  # noqa: E402
from gearsim.dynamics.model import static_state  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.numerics import batch  # noqa: E402
from gearsim.numerics.integrate import PeriodSummaries  # noqa: E402

RTOL, ATOL = 1e-8, 1e-10


def make_rhs(p: ModelParameters):
    w, b, eps, xi2 = p.w, p.b, p.eps, 2 * p.xi
    fm, few2, phi = p.Fm, p.Fe * w * w, p.phi_e
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    rp, rg = p.rho_p, p.rho_g
    kap = (p.kappa_py, p.kappa_pz, p.kappa_gy, p.kappa_gz)
    zb = (2 * p.xi_py, 2 * p.xi_pz, 2 * p.xi_gy, 2 * p.xi_gz)
    gam = p.friction

    def rhs(t, y):
        x, v = y[0], y[1]
        c = math.cos(w * t)
        stiff = 1.0 + eps * c
        s0 = 1.0 if (x > b or x < -b) else 0.0
        f = x - b if x > b else (x + b if x < -b else 0.0)
        F = stiff * f + xi2 * v
        fric = 1.0 + gam * (1.0 if math.sin(w * t) >= 0 else -1.0)
        drive = fm + few2 * math.cos(w * t + phi)
        a_py = -zb[0] * y[3] - kap[0] * y[2] - rp * F * ca
        a_pz = -zb[1] * y[5] - kap[1] * y[4] - rp * F * sa
        a_gy = -zb[2] * y[7] - kap[2] * y[6] + rg * F * ca
        a_gz = -zb[3] * y[9] - kap[3] * y[8] + rg * F * sa
        acc = drive - F * fric + (a_py - a_gy) * ca + (a_pz - a_gz) * sa
        out = [v, acc, y[3], a_py, y[5], a_pz, y[7], a_gy, y[9], a_gz]
        if len(y) == 20:
            dF = stiff * s0 * y[10] + xi2 * y[11]
            d_py = -zb[0] * y[13] - kap[0] * y[12] - rp * dF * ca
            d_pz = -zb[1] * y[15] - kap[1] * y[14] - rp * dF * sa
            d_gy = -zb[2] * y[17] - kap[2] * y[16] + rg * dF * ca
            d_gz = -zb[3] * y[19] - kap[3] * y[18] + rg * dF * sa
            dacc = -dF * fric + (d_py - d_gy) * ca + (d_pz - d_gz) * sa
            out += [y[11], dacc, y[13], d_py, y[15], d_pz, y[17], d_gy, y[19], d_gz]
        return out

    def up(t, y):
        return y[0] - b

    def lo(t, y):
        return y[0] + b

    return rhs, up, lo


def ivp_periods(p, y, k0, m, tangent):
    """m periods from state y at period k0: (summaries, final state, n_rhs_evals)."""
    rhs, up, lo = make_rhs(p)
    T = 2 * math.pi / p.w
    b = p.b
    sec = np.zeros((m, 10))
    nf = np.zeros(m, dtype=np.int64)
    nb = np.zeros(m, dtype=np.int64)
    fl = np.zeros((m, 6))
    nfev = 0
    y = np.array(y, dtype=float)
    for k in range(m):
        t0, t1 = (k0 + k) * T, (k0 + k + 1) * T
        sec[k] = y[:10]
        sol = solve_ivp(
            rhs,
            (t0, t1),
            y,
            method="RK45",
            rtol=RTOL,
            atol=ATOL,
            events=(up, lo),
            dense_output=True,
        )
        nfev += sol.nfev
        te_up, te_lo = sol.t_events
        ye_up, ye_lo = sol.y_events
        # entries: upward through +b (face), downward through -b (back)
        nf[k] = sum(1 for ye in ye_up if ye[1] > 0)
        nb[k] = sum(1 for ye in ye_lo if ye[1] < 0)
        cross = np.sort(np.concatenate([[t0], te_up, te_lo, [t1]]))
        mids = 0.5 * (cross[1:] + cross[:-1])
        xm = sol.sol(mids)[0] if len(mids) else np.zeros(0)
        tdis = float(np.sum(np.diff(cross)[np.abs(xm) < b]))
        ts = np.linspace(t0, t1, 65)
        ys = sol.sol(ts)
        x, v = ys[0], ys[1]
        f = np.where(x > b, x - b, np.where(x < -b, x + b, 0.0))
        F = (1 + p.eps * np.cos(p.w * ts)) * f + 2 * p.xi * v
        y = sol.y[:, -1].copy()
        ly = 0.0
        if tangent:
            nrm = float(np.linalg.norm(y[10:]))
            ly = math.log(nrm) if nrm > 0 else 0.0
            y[10:] /= nrm
        fl[k] = (tdis, F.max(), F.min(), x.max(), x.min(), ly)
    s = PeriodSummaries(sec, nf, nb, *(fl[:, i].copy() for i in range(6)))
    return s, y, nfev


def ivp_cell(p, st):
    """simulate_cell's logic (fresh start) on solve_ivp summaries: (classification, nfev)."""
    y = static_state(p.to_array())
    _, y, nfev = ivp_periods(p, y, 0, st.transient, False)
    k = st.transient
    yt = np.concatenate([y, initial_tangent(p)])
    parts, measured, n = [], 0, 0
    while measured < st.max_periods:
        m = min(st.chunk, st.max_periods - measured)
        s, yt, ev = ivp_periods(p, yt, k, m, True)
        nfev += ev
        parts.append(s)
        k += m
        measured += m
        s = PeriodSummaries.concat(parts)
        n = estimate_period(
            s.section[:, 0],
            s.section[:, 1],
            float(s.xmax.max() - s.xmin.min()),
            p.w,
            st.n_max,
            st.period_rtol,
        )
        if n > 0:
            break
    s = PeriodSummaries.concat(parts)
    window = s.tail(n * max(1, min(len(s), 4 * max(n, 8)) // n)) if n > 0 else s
    cls = classify_motion(
        window,
        p,
        n=n,
        lyap_threshold=st.lyap_threshold,
    )
    return cls, nfev, k


CELLS = [(0.3, 0.85), (1.0, 1.02), (0.15, 0.76), (1.0, 1.30), (0.15, 1.53), (0.3, 1.45)]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    st = IntegrationSettings()
    cells = [ModelParameters(w=w, b=b) for b, w in (CELLS[:3] if args.quick else CELLS)]
    # batched path, per cell: the cell in a full 8-lane block (8 copies; CPU time / 8), i.e. its
    # cost inside a tile; and the cell alone (one lane busy, 7 idle)
    chains.simulate_cells(cells[:1], settings=st)  # warm
    rb, full, single = [], [], []
    for p in cells:
        reps = []
        for _ in range(3):
            t = time.process_time()
            r8 = chains.simulate_cells([p] * batch.LANES, settings=st)
            reps.append((time.process_time() - t) / batch.LANES)
        full.append(float(np.median(reps)))
        rb.append(r8[0])
        t = time.process_time()
        chains.simulate_cells([p], settings=st)
        single.append(time.process_time() - t)
    rows = []
    for p, r, t8, t1 in zip(cells, rb, full, single, strict=True):
        simulate_cell(p, settings=st)
        t = time.process_time()
        ref = simulate_cell(p, settings=st).classification
        t_dp5 = time.process_time() - t
        t = time.process_time()
        cls, nfev, periods = ivp_cell(p, st)
        t_ivp = time.process_time() - t
        row = {
            "w": p.w,
            "b": p.b,
            "label_ivp": f"{cls.label} {cls.label_npq}",
            "label_batched": f"{r.classification.label} {r.classification.label_npq}",
            "label_dp5": f"{ref.label} {ref.label_npq}",
            "equal": cls.label == r.classification.label == ref.label
            and cls.label_npq == r.classification.label_npq,
            "ivp_s": t_ivp,
            "ivp_nfev": nfev,
            "ivp_periods": periods,
            "dp5_simulate_cell_s": t_dp5,
            "batched_full_block_s": t8,
            "batched_single_lane_s": t1,
            "ratio_ivp_over_batched": t_ivp / t8,
            "ratio_ivp_over_dp5": t_ivp / t_dp5,
            "ratio_ivp_over_batched_single_lane": t_ivp / t1,
        }
        rows.append(row)
        print(
            {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()},
            "load",
            loadavg(),
            flush=True,
        )
    eq = [r for r in rows if r["equal"]]
    out = {
        "solve_ivp": {"method": "RK45", "rtol": RTOL, "atol": ATOL},
        "settings": st.to_dict(),
        "cells": rows,
        "equal_classification": f"{len(eq)}/{len(rows)}",
        "ratio_median_equal_cells": float(np.median([r["ratio_ivp_over_batched"] for r in eq]))
        if eq
        else None,
        "ratio_ivp_over_dp5_median": float(np.median([r["ratio_ivp_over_dp5"] for r in rows])),
        "ratio_single_lane_median_equal_cells": float(
            np.median([r["ratio_ivp_over_batched_single_lane"] for r in eq])
        )
        if eq
        else None,
    }
    print(
        "ratio (median, equal cells):",
        out["ratio_median_equal_cells"],
        "single lane:",
        out["ratio_single_lane_median_equal_cells"],
    )
    print(save("solve_ivp", out))


if __name__ == "__main__":
    sys.exit(main())
