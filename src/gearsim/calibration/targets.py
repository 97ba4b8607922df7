"""The paper's targets and the one objective over them (pure: no simulation).

Targets (:data:`TARGETS`, the paper's values from :mod:`gearsim.analysis.paper`; each with a
tolerance ``tol``, the error is counted in tolerances):

* the 12 standard-sweep landmarks (:data:`gearsim.analysis.paper.PAPER_LANDMARKS`), tol 0.02
  in w;
* the backlash threshold (tol 0.01): without back contact the model is invariant under
  scaling ``x, Fm, Fe, b`` together, so the threshold fixes the *scale* ``Fm`` and is matched by
  construction (:func:`gearsim.calibration.fidelity.measure`);
* the damping threshold (tol 0.01): the xi above which only 0/1T and 1/1T remain;
* DC after the jump (tol 0.03) and the grazing-to-jump gap in w (tol 0.02);
* the pattern sequences of Fig 8 (b = 0.15) and Fig 15 (xi = 0.05, 0.09, 0.15), tol 1 pattern:
  the error is the insert/delete distance between the paper's sequence and ours
  (:func:`sequence_distance`; the paper's "..." matches any run of patterns);
* the three motions of Figs 9-11 at their point (:data:`gearsim.analysis.paper.COEXIST_POINT`),
  tol 1: the error is the number of them that the attractor search does not find there.

Cost (:func:`score`)::

    c_t = min((e_t / tol_t)^2, cap^2)       cap = 10 (a landmark not found: 10 tolerances = 0.2)
    J   = sqrt(sum_t c_t / number of targets)

so J is the RMS error in tolerances over all 21 targets (J <= 1: on average within tolerance).
Nothing in the model reads the paper's values.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from gearsim.analysis.paper import (
    COEXIST_POINT,
    JUMP_DC_TOL,
    LANDMARK_TOL,
    PAPER_B_THRESHOLD,
    PAPER_COEXIST,
    PAPER_GAP,
    PAPER_JUMP_DC,
    PAPER_LANDMARKS,
    PAPER_SEQUENCES,
    PAPER_XI_THRESHOLD,
    SEQUENCE_SWEEPS,
    THRESHOLD_TOL,
)

CAP = 10.0


@dataclass(frozen=True)
class Target:
    key: str
    paper: float | str
    tol: float
    unit: str
    text: str


def _targets() -> tuple[Target, ...]:
    out = [Target(pl.key, pl.w, LANDMARK_TOL, "w", pl.text) for pl in PAPER_LANDMARKS]
    out += [
        Target("b_threshold", PAPER_B_THRESHOLD, THRESHOLD_TOL, "b",
               "backlash above which no double-sided impact occurs"),
        Target("xi_threshold", PAPER_XI_THRESHOLD, THRESHOLD_TOL, "xi",
               "damping above which only 0/1T and 1/1T remain"),
        Target("dc_jump", PAPER_JUMP_DC, JUMP_DC_TOL, "DC",
               "disengagement duty cycle after the jump"),
        Target("gap", PAPER_GAP, 0.02, "w", "grazing-to-jump gap (jump - first grazing)"),
    ]
    out += [Target(f"seq_{k}", " ".join(v), 1.0, "patterns",
                   f"pattern sequence at {SEQUENCE_SWEEPS[k][0]} = {SEQUENCE_SWEEPS[k][1]}")
            for k, v in PAPER_SEQUENCES.items()]
    out.append(Target("coexist", " ".join(PAPER_COEXIST), 1.0, "motions",
                      f"Figs 9-11 motions at b = {COEXIST_POINT['b']}, w = {COEXIST_POINT['w']} "
                      "(attractor search)"))
    return tuple(out)


TARGETS: tuple[Target, ...] = _targets()
TARGET_KEYS = tuple(t.key for t in TARGETS)
LANDMARK_KEYS = tuple(pl.key for pl in PAPER_LANDMARKS)


def sequence_distance(paper: Sequence[str], ours: Sequence[str]) -> int:
    """Insert/delete distance between two pattern sequences; ``"..."`` in ``paper`` absorbs any
    run (possibly empty) of ``ours`` at no cost.

    Equal sequences give 0; one extra or one missing pattern gives 1; a substituted pattern 2.
    """
    m, n = len(paper), len(ours)
    INF = 10**9
    d = [[INF] * (n + 1) for _ in range(m + 1)]
    d[0][0] = 0
    for j in range(1, n + 1):
        d[0][j] = j
    for i in range(1, m + 1):
        tok = paper[i - 1]
        if tok == "...":
            best = INF
            for j in range(n + 1):
                best = min(best, d[i - 1][j])
                d[i][j] = best
            continue
        d[i][0] = d[i - 1][0] + 1
        for j in range(1, n + 1):
            v = min(d[i - 1][j] + 1, d[i][j - 1] + 1)
            if tok == ours[j - 1]:
                v = min(v, d[i - 1][j - 1])
            d[i][j] = v
    return int(d[m][n])


@dataclass
class Measured:
    """What one model form with one parameter set gives for every target (NaN/None: not
    measured or not found)."""

    landmarks: dict[str, float | None] = field(default_factory=dict)
    landmark_source: dict[str, str] = field(default_factory=dict)  # exact | grid
    b_threshold: float = math.nan  # in the paper's scale (after Fm is derived)
    b_star_raw: float = math.nan  # b* at the measured Fm
    Fm_derived: float = math.nan
    xi_threshold: float = math.nan
    dc_jump: float = math.nan
    gap: float = math.nan
    sequences: dict[str, list[str]] = field(default_factory=dict)
    coexist: list[str] | None = None
    gated: bool = False
    kmax: dict[str, Any] = field(default_factory=dict)  # Kmax readings at the jump (exact level)
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Measured:
        """From a :meth:`to_dict` record (unknown keys ignored)."""
        return cls(**{k: v for k, v in d.items() if k in cls.__dataclass_fields__})


def target_errors(m: Measured) -> dict[str, float]:
    """Signed error of every target (NaN: not measured / not found)."""
    e: dict[str, float] = {}
    for pl in PAPER_LANDMARKS:
        v = m.landmarks.get(pl.key)
        e[pl.key] = math.nan if v is None or not np.isfinite(v) else pl.error(float(v))
    e["b_threshold"] = m.b_threshold - PAPER_B_THRESHOLD
    e["xi_threshold"] = m.xi_threshold - PAPER_XI_THRESHOLD
    e["dc_jump"] = m.dc_jump - PAPER_JUMP_DC
    e["gap"] = m.gap - PAPER_GAP
    for k, paper in PAPER_SEQUENCES.items():
        ours = m.sequences.get(k)
        e[f"seq_{k}"] = math.nan if ours is None else float(sequence_distance(paper, ours))
    e["coexist"] = (math.nan if m.coexist is None
                    else float(sum(1 for x in PAPER_COEXIST if x not in m.coexist)))
    return e


def score(m: Measured, *, cap: float = CAP, keys: Sequence[str] = TARGET_KEYS
          ) -> tuple[float, dict[str, float]]:
    """The one objective: ``J = sqrt(mean_t min((e_t / tol_t)^2, cap^2))`` over the targets
    ``keys`` (default: all of :data:`TARGETS`); a target not measured or not found counts
    ``cap``. Returns ``(J, per-target c_t)``."""
    errs = target_errors(m)
    wanted = set(keys)
    terms: dict[str, float] = {}
    for t in TARGETS:
        if t.key not in wanted:
            continue
        e = errs[t.key]
        terms[t.key] = cap**2 if not np.isfinite(e) else min((e / t.tol) ** 2, cap**2)
    return math.sqrt(sum(terms.values()) / len(terms)), terms


def landmark_part(m: Measured) -> float:
    """:func:`score` over the 12 landmarks only (the search's gate)."""
    return score(m, keys=LANDMARK_KEYS)[0]
