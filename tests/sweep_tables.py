"""Hand-built sweep tables shared by the tests (orbit diagrams with known landmarks and
patterns; no simulation)."""

from __future__ import annotations

import numpy as np
import pandas as pd


def row(w, npq=None, motion="periodic", I=None, dc=0.0, kmax=1.0):
    if npq is not None:
        n, p, q = (int(v) for v in npq.split("-"))
        I = I if I is not None else (2 if p and q else 1 if p else -1 if q else 0)
        label = f"{I}/{n}T"
    else:
        n, p, q, I, label, npq = 0, None, None, 1 if I is None else I, motion, ""
    return {"value": w, "motion": motion, "I": I, "n": n, "p": p, "q": q, "label": label,
            "label_npq": npq, "dc": dc, "kmax_peak_static": kmax, "kmax_peak_mean": 2 * kmax,
            "kmax_section_mean": kmax, "kmax_section_static": kmax}


def paper_like(w0=0.0, quasi_at=None):
    """A sweep with every landmark of the paper, each between two 0.01-spaced values."""
    seq = [
        (0.50, "1-0-0", 0.0), (0.56, "1-1-0", 0.05), (0.65, "1-1-0", 0.66), (0.98, "2-2-0", 0.6),
        (1.07, "2-1-0", 0.5), (1.33, "4-2-0", 0.6), (1.35, "4-3-0", 0.6), (1.37, "8-6-0", 0.6),
        (1.39, "chaos", 0.7), (1.64, "8-6-0", 0.6), (1.67, "4-3-0", 0.6), (1.71, "2-2-0", 0.5),
        (1.86, "1-1-0", 0.4),
    ]
    rows = []
    ws = np.round(np.arange(0.50, 2.0, 0.01) + w0, 4)
    for w in ws:
        cur = [s for s in seq if s[0] <= w + 1e-9][-1]
        dc = cur[2]
        if cur[1] == "1-1-0" and cur[0] == 0.56:
            dc = 0.05 + (w - 0.56)  # DC grows before the jump
        if cur[1] == "chaos":
            rows.append(row(w, motion="chaos", dc=dc))
        elif quasi_at is not None and abs(w - quasi_at) < 1e-9:
            rows.append(row(w, motion="quasi-periodic", dc=dc))
        else:
            rows.append(row(w, cur[1], dc=dc))
    return pd.DataFrame(rows)


def _row(value, motion, I, n, p, q, dc, xs, **extra):
    label = f"{I}/{n}T" if motion == "periodic" else motion
    return {
        "parameter": "w", "value": value, "direction": "forward", "motion": motion,
        "status": "ok", "I": I, "n": n if motion == "periodic" else 0,
        "p": p if motion == "periodic" else None, "q": q if motion == "periodic" else None,
        "label": label, "label_npq": f"{n}-{p}-{q}" if motion == "periodic" else "",
        "dc": dc, "kmax": 1.0 + dc, "kmax_peak_mean": 2 + dc, "kmax_peak_static": 1.0 + dc,
        "kmax_section_mean": 1.0, "kmax_section_static": 0.5, "kmin_peak_mean": 0.0,
        "lyapunov": 0.1 if motion == "chaos" else -0.1, "x_min": min(xs) - 0.1,
        "x_max": max(xs) + 0.1, "converged": True, "window_periods": 32, "periods": 100,
        "steps": 1000, "poincare_x": list(xs), "poincare_v": [0.1 * x for x in xs], **extra,
    }


def synthetic_sweep(n: int = 24) -> pd.DataFrame:
    """0/1T -> 1/1T (grazing) -> jump -> 1/2T (PD) -> chaos -> 1/2T -> 1/1T, plus some I = 2."""
    rows = []
    rng = np.random.default_rng(0)
    for k, w in enumerate(np.linspace(0.1, 2.5, n)):
        f = k / (n - 1)
        if f < 0.2:
            rows.append(_row(w, "periodic", 0, 1, 0, 0, 0.0, [1.1]))
        elif f < 0.3:
            rows.append(_row(w, "periodic", 1, 1, 1, 0, 0.05, [1.0]))
        elif f < 0.45:
            rows.append(_row(w, "periodic", 1, 1, 1, 0, 0.6, [0.8]))
        elif f < 0.55:
            rows.append(_row(w, "periodic", 1, 2, 2, 0, 0.5, [0.7, 0.9]))
        elif f < 0.7:
            rows.append(_row(w, "chaos", 1, 0, 0, 0, 0.55, list(rng.uniform(0.4, 1.0, 20))))
        elif f < 0.8:
            rows.append(_row(w, "periodic", 2, 2, 2, 1, 0.3, [0.2, -0.3]))
        else:
            rows.append(_row(w, "periodic", 1, 1, 1, 0, 0.35, [0.95]))
    return pd.DataFrame(rows)
