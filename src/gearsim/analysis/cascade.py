"""The chaotic band of a plane along one line of fixed second parameter: the period-doubling
cascade located by continuation, the ratio of its successive intervals, its accumulation
(the chaotic band's onset) and, read from the grid, where the band ends.

* :func:`grid_cascade` reads the row's labels: the last period-1 cell before the first
  chaotic cell (the cascade's start), the periods met on the way, the band's first and last
  chaotic cells and what follows the band (``exit``: ``cascade`` when the periods after it
  halve again, ``crisis`` when the band ends abruptly into anything else: a motion of another
  impact state or period, named as read).
* :func:`locate_cascade` continues the period-1 orbit from the cascade's start towards the
  band (:func:`gearsim.analysis.continuation.continue_orbit`, switching at each doubling to
  the doubled branch, ``depth`` times: periods 2, 4, ..., ``2**depth``) and
  :func:`cascade_doublings` reads the doublings off the branches: ``w_k`` the doubling of
  period ``2**k``, ``delta_k = (w_k - w_{k-1}) / (w_{k+1} - w_k)``, the accumulation
  ``w_inf = w_K + (w_K - w_{K-1}) / (delta_K - 1)`` (the geometric tail of the intervals;
  with a single interval Feigenbaum's ``delta`` stands in), and whether a grazing lies
  between successive doublings (then the cascade is not smooth and ``delta`` need not be
  Feigenbaum's).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

#: Feigenbaum's constant: the ratio of successive doubling intervals of a smooth cascade
FEIGENBAUM = 4.669201609


def _label(r) -> str:
    return str(r["label"])


def grid_cascade(row: pd.DataFrame, x: str = "x") -> dict[str, Any] | None:
    """The cascade and the chaotic band as a plane row's labels read them (``row``: one row
    of cells, columns ``x`` (the axis), ``motion``, ``n``, ``I``, ``label``); None when the row
    has no chaotic cell preceded by a period-1 cell."""
    r = row.sort_values(x).reset_index(drop=True)
    chaos = np.nonzero((r["motion"] == "chaos").to_numpy())[0]
    if not len(chaos):
        return None
    first = int(chaos[0])
    ones = np.nonzero(((r["motion"] == "periodic") & (r["n"] == 1)).to_numpy()[:first])[0]
    if not len(ones):
        return None
    start = int(ones[-1])
    periods = [int(v) for v in r.loc[start:first - 1, "n"]]
    seen = list(dict.fromkeys(p for p in periods if p > 0))
    # the band: chaotic cells with gaps of at most 2 non-chaotic cells (windows) between
    last = first
    for k in chaos[1:]:
        if k - last > 3:
            break
        last = int(k)
    out = {"start": float(r.at[start, x]), "onset": float(r.at[first, x]),
           "onset_lo": float(r.at[first - 1, x]), "periods": seen,
           "end": float(r.at[last, x]), "before_onset": _label(r.loc[first - 1]),
           "after_end": None, "exit": None}
    if last + 1 < len(r):
        after = r.loc[last + 1]
        out["after_end"] = _label(after)
        n_after = int(after["n"]) if after["motion"] == "periodic" else 0
        nxt = r.loc[last + 1:]
        per = nxt[nxt["motion"] == "periodic"]["n"].astype(int).tolist()
        # an inverse cascade: the periods after the band halve (..., 8, 4, 2)
        halving = (n_after >= 2 and n_after & (n_after - 1) == 0 and
                   any(p == n_after // 2 for p in per[:40]))
        out["exit"] = "cascade" if halving else "crisis"
    return out


def cascade_doublings(branches: pd.DataFrame, start: float, stop: float) -> pd.DataFrame:
    """The cascade in a continuation table: for ``k = 0, 1, ...`` the doubling of period
    ``2**k`` nearest after the previous one in the direction ``start -> stop``; columns
    ``period``, ``value``, ``interval`` (from the previous doubling), ``ratio`` (the previous
    interval over this one), ``grazing_before`` (a grazing of the branch between the previous
    doubling and this one)."""
    d = 1.0 if stop > start else -1.0
    ev = branches[branches["event"] != ""]
    pdp = ev[ev["event"] == "period_doubling"]
    graz = ev[ev["event"] == "grazing"]
    rows: list[dict[str, Any]] = []
    prev = start
    n = 1
    while True:
        cand = pdp[(pdp["period"] == n) & ((pdp["value"] - prev) * d > 0)
                   & ((pdp["value"] - stop) * d <= 0)]
        if not len(cand):
            break
        w = float(cand.loc[((cand["value"] - prev) * d).idxmin(), "value"])
        between = graz[(graz["period"] == n) & ((graz["value"] - prev) * d > 0)
                       & ((graz["value"] - w) * d < 0)]
        rows.append({"period": n, "value": w, "grazing_before": bool(len(between)) and n > 1})
        prev, n = w, 2 * n
    out = pd.DataFrame(rows, columns=["period", "value", "grazing_before"])
    out["interval"] = out["value"].diff().abs()
    out["ratio"] = out["interval"].shift(1) / out["interval"]
    return out


def accumulation(doublings: pd.DataFrame) -> tuple[float, float]:
    """``(w_inf, delta)``: the accumulation point of the located cascade and the ratio used
    (the last measured one; Feigenbaum's where fewer than three doublings are located)."""
    if len(doublings) < 2:
        return math.nan, math.nan
    w = doublings["value"].to_numpy(float)
    ratios = doublings["ratio"].dropna().to_numpy(float)
    delta = float(ratios[-1]) if len(ratios) else FEIGENBAUM
    if not delta > 1.0:
        return math.nan, delta
    return float(w[-1] + (w[-1] - w[-2]) / (delta - 1.0)), delta


def locate_cascade(params, name: str, start: float, stop: float, *, depth: int = 4,
                   progress=None, deadline: float | None = None) -> pd.DataFrame:
    """The continuation of the period-1 orbit at ``name = start`` towards ``stop``, switching
    ``depth`` times at period doublings (the branch table of
    :func:`gearsim.analysis.continuation.continue_orbit`). The start orbit is Newton's from
    the state simulated from rest at ``start``."""
    from gearsim.analysis.continuation import continue_orbit
    from gearsim.analysis.continuation_options import Continuation
    from gearsim.analysis.orbits import SEEDING, find_periodic_orbit
    from gearsim.cell.simulate import simulate_cell

    p0 = params.with_(**{name: start})
    seed = simulate_cell(p0, settings=SEEDING).final_state
    orbit = find_periodic_orbit(p0, 1, seed, grazing=False)
    cfg = Continuation(ds=0.01, ds_max=0.02, switch_depth=depth, max_points=300,
                       progress=progress, deadline=deadline)
    return continue_orbit(p0, name, start, stop, orbit, config=cfg)
