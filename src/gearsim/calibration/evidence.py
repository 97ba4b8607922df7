"""Evidence for a miss: per target, the closest any logged evaluation of any form came."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.search import logged_evaluations
from gearsim.calibration.targets import LANDMARK_KEYS, TARGETS, Measured, target_errors


def best_per_target(log_dir: str | Path) -> dict[str, dict[str, Any]]:
    """For every target: the smallest error any logged evaluation of any form reached, with
    that evaluation's form, level (coarse grid read / exact), J and how many evaluations
    measured the target. Evidence for a miss: no tested form got closer within its search."""
    tol = {t.key: t.tol for t in TARGETS}
    best: dict[str, dict[str, Any]] = {}
    for form, level, rec in logged_evaluations(log_dir):
        errs = target_errors(Measured.from_dict(rec["measured"]))
        for k, e in errs.items():
            if not np.isfinite(e):
                continue
            b = best.setdefault(k, {"n": 0, "n_hit": 0})
            b["n"] += 1
            if "error" not in b or abs(e) < abs(b["error"]):
                b.update(error=float(e), form=form, level=level, J=float(rec["J"]),
                         x=rec["x"])
            if abs(e) <= tol[k] * (1 + 1e-9):
                # the trade-off: of the evaluations that hit this target, the lowest J and
                # which landmarks miss 0.02 there
                b["n_hit"] += 1
                if "hit_J" not in b or rec["J"] < b["hit_J"]:
                    b.update(hit_J=float(rec["J"]), hit_form=form, hit_level=level,
                             hit_x=rec["x"],
                             hit_misses={q: (None if not np.isfinite(v) else float(v))
                                         for q, v in errs.items()
                                         if q != k and q in LANDMARK_KEYS and
                                         not (np.isfinite(v) and abs(v) <= tol[q])})
    return best
