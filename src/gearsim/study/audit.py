"""The numerical audit of a plane: a deterministic sample of its cells re-simulated with an
independent integrator (adaptive DP5 at tightened tolerances) from the same start states, and
their labels compared with the pipeline's."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from gearsim.cell.simulate import chain_start, simulate_cell
from gearsim.study.config import Study


def audit_settings(study: Study):
    """The audit's reference: the adaptive DP5 integrator, whatever method produced the cells
    (an independent integrator, not just a finer step of the same one), at ``audit.tighten``
    times the configuration's DP5 tolerances and half its step cap; the cell plan (transient,
    chunks, period test, ``transient_recurrence``) is the configuration's. ``tighten: 100`` is
    :meth:`IntegrationSettings.tightened`; the evidence for the default is in
    benchmarks/CHANGELOG.md (l)."""
    st = study.settings.with_(method="dp5")
    return st.tightened(float(study.config["audit"].get("tighten", 10)))


def audit_frame(study: Study, plane: str, cells, progress=None):
    """Re-simulate a deterministic sample of cells with DP5 at tightened tolerance
    (:func:`audit_settings`).

    Each audited cell starts exactly where the pipeline started it: from the final state of its
    left neighbour in the row (continuation), or from rest for the first cell of a row and after
    a neighbour that does not seed the chain (:func:`gearsim.cell.simulate.chain_start`).
    """
    aud = study.config["audit"]
    n = len(cells)
    k = int(round(aud["fraction"] * n))
    if aud["fraction"] > 0:
        k = max(k, 1)
    rng = np.random.default_rng(int(aud["seed"]))
    pick = np.sort(rng.choice(n, size=min(k, n), replace=False))
    base = study.parameters(plane=plane).model
    pl = study.config["planes"][plane]
    tight = audit_settings(study)
    index = {
        (int(i), int(j)): r for r, (i, j) in enumerate(zip(cells["i"], cells["j"], strict=True))
    }
    rows = []
    t0 = time.perf_counter()
    for m, r in enumerate(pick):
        c = cells.iloc[r]
        i, j = int(c["i"]), int(c["j"])
        params = base.with_(**{pl["x"]["name"]: float(c["x"]), pl["y"]["name"]: float(c["y"])})
        left = index.get((i - 1, j))
        u0, start = chain_start(cells.iloc[left] if left is not None else None)
        res = simulate_cell(params, u0, settings=tight, start_period=start)
        t = res.row()
        rows.append(
            {
                "plane": plane,
                "i": i,
                "j": j,
                "x": float(c["x"]),
                "y": float(c["y"]),
                "label": c["label"],
                "label_npq": c["label_npq"],
                "tight_label": t["label"],
                "tight_label_npq": t["label_npq"],
                "tight_I": t["I"],
                "tight_dc": t["dc"],
                "tight_kmax": t["kmax"],
                "tight_lyapunov": t["lyapunov"],
                "agree": bool(t["label"] == c["label"] and t["label_npq"] == c["label_npq"]),
            }
        )
        if progress:
            progress(m + 1, len(pick), time.perf_counter() - t0)
    return pd.DataFrame(
        rows,
        columns=[
            "plane",
            "i",
            "j",
            "x",
            "y",
            "label",
            "label_npq",
            "tight_label",
            "tight_label_npq",
            "tight_I",
            "tight_dc",
            "tight_kmax",
            "tight_lyapunov",
            "agree",
        ],
    )
