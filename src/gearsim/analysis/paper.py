"""What the paper states (Liu et al., PLOS ONE 2025), once: the landmarks of the standard sweep,
the values at the jump, the backlash and damping thresholds, the pattern sequences of Figs 8 and
15, the motions of Figs 5, 6 and 9-11, and the tolerances a comparison with them allows.

Data only. Calibration (its targets), the report, the figures and the explorer read these values;
nothing in the model does. The landmarks are those of /work/shared/MODEL.md's table (paper Sect
3.1), the sequences those of the text of Fig 8 (Sect 3.2) and the list of Fig 15 (Sect 3.3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class PaperLandmark:
    """One row of the paper's landmark table (standard parameters, forward sweep in w)."""

    key: str
    kind: str
    w: float
    w_range: tuple[float, float]  # interval the paper gives (w, w) when a single value
    from_npq: str | None  # pattern before ('chaos' for chaos); None = any
    to_npq: str | None
    text: str

    def error(self, w: float) -> float:
        """Signed distance of ``w`` from the paper's interval (0 inside it)."""
        lo, hi = self.w_range
        if w < lo:
            return w - lo
        if w > hi:
            return w - hi
        return 0.0


def _pl(key, kind, w, fr, to, text, w_range=None) -> PaperLandmark:
    return PaperLandmark(key, kind, w, w_range or (w, w), fr, to, text)


#: the values at the jump (Sect 3.1): the duty cycle and Kmax after it
PAPER_JUMP_DC = 0.66
PAPER_JUMP_KMAX = 1.311
#: Fig 17's range of Kmax at the jump for small xi
PAPER_KMAX_FIG17 = (1.8, 2.1)

#: The paper's landmarks, in sweep order (Sect 3.1).
PAPER_LANDMARKS: tuple[PaperLandmark, ...] = (
    _pl("grazing_1", "grazing", 0.569, "1-0-0", "1-1-0", "grazing 1-0-0 -> 1-1-0 (I 0 -> 1)"),
    _pl("jump", "jump", 0.66, None, None,
        f"jump: DC -> {PAPER_JUMP_DC}, Kmax -> {PAPER_JUMP_KMAX}"),
    _pl("pd_1_2", "period_doubling", 0.988, "1-1-0", "2-2-0", "period doubling 1-1-0 -> 2-2-0"),
    _pl("grazing_2", "grazing", 1.072, "2-2-0", "2-1-0", "grazing 2-2-0 -> 2-1-0"),
    _pl("pd_2_4", "period_doubling", 1.33, "2-1-0", "4-2-0", "period doubling 2-1-0 -> 4-2-0"),
    _pl("grazing_4", "grazing", 1.354, "4-2-0", "4-3-0", "grazing 4-2-0 -> 4-3-0"),
    _pl("pd_4_8", "period_doubling", 1.377, None, "8-6-0",
        "period doubling -> 8-6-0 (1.37-1.384)", w_range=(1.37, 1.384)),
    _pl("chaos_onset", "chaos_onset", 1.396, None, "chaos", "chaos onset"),
    _pl("ipd_chaos_8", "inverse_period_doubling", 1.642, "chaos", "8-6-0", "chaos -> 8-6-0"),
    _pl("ipd_8_4", "inverse_period_doubling", 1.672, "8-6-0", "4-3-0", "8-6-0 -> 4-3-0"),
    _pl("ipd_4_2", "inverse_period_doubling", 1.714, "4-3-0", "2-2-0", "4-3-0 -> 2-2-0"),
    _pl("period_one", "period_one", 1.864, "2-2-0", "1-1-0", "back to period 1 (2-2-0 -> 1-1-0)"),
)
PAPER_LANDMARK = {pl.key: pl for pl in PAPER_LANDMARKS}
#: the grazing-to-jump gap in w (jump - first grazing)
PAPER_GAP = round(PAPER_LANDMARK["jump"].w - PAPER_LANDMARK["grazing_1"].w, 6)

#: the backlash above which no double-sided impact occurs (Sect 3.2, the (w, b) plane)
PAPER_B_THRESHOLD = 0.4125
#: the damping above which only 0/1T and 1/1T remain (Sect 3.3, the (w, xi) plane)
PAPER_XI_THRESHOLD = 0.1436
#: what the paper has for a plane of these axes
PAPER_PLANES = {("w", "b"): f"Figs 7, 12, 13 and the backlash threshold b = {PAPER_B_THRESHOLD}",
                ("w", "xi"): f"Figs 14, 16, 17 and the damping threshold xi = {PAPER_XI_THRESHOLD}"}

#: the sweeps of Figs 8 and 15: name -> (fixed parameter, value); w is swept
PAPER_SWEEPS = {"b015": ("b", 0.15), "b025": ("b", 0.25), "b035": ("b", 0.35),
                "xi005": ("xi", 0.05), "xi009": ("xi", 0.09), "xi015": ("xi", 0.15)}
#: the paper's ellipsis in a sequence: any run of patterns
ELLIPSIS = "..."
#: The pattern sequences the paper lists (Fig 8a, Fig 15a-c); Figs 8b and 8c are described in
#: words only (:data:`PAPER_SEQUENCE_TEXT`).
PAPER_SEQUENCES: dict[str, tuple[str, ...]] = {
    "b015": ("0/1T", "1/1T", "2/1T", "2/2T", "1/2T", "1/1T"),
    "xi005": ("0/1T", "1/1T", "1/2T", "1/4T", ELLIPSIS, "chaos", "1/8T", "1/4T", "1/2T", "1/1T"),
    "xi009": ("0/1T", "1/1T", "1/2T", "1/4T", "1/2T", "1/1T"),
    "xi015": ("0/1T", "1/1T"),
}
#: the sweeps of the listed sequences
SEQUENCE_SWEEPS = {k: PAPER_SWEEPS[k] for k in PAPER_SEQUENCES}
#: the paper's words for every sweep of Figs 8 and 15 (G = grazing, PD = period doubling)
PAPER_SEQUENCE_TEXT = {
    "b015": "0/1T -> 1/1T -> 2/1T -> 2/2T -> 1/2T -> 1/1T (Fig 8a)",
    "b025": "non-impact interval unchanged; double-sided interval contracts, tooth-surface "
            "interval expands; high-period double-sided motions (period 4, 8) appear (Fig 8b)",
    "b035": "double-sided interval contracts further; double-sided motions degenerate to "
            "2/4T and 2/2T (Fig 8c)",
    "xi005": "0/1T -G-> 1/1T -PD-> 1/2T -PD-> 1/4T -PD-> ... chaos ... -PD-> 1/8T -> 1/4T -> "
             "1/2T -> 1/1T (Fig 15a)",
    "xi009": "0/1T -G-> 1/1T -PD-> 1/2T -PD-> 1/4T -PD-> 1/2T -PD-> 1/1T (Fig 15b)",
    "xi015": "0/1T -G-> 1/1T (Fig 15c)",
}


def listed_patterns(sequence: Sequence[str]) -> list[str]:
    """The patterns a sequence names, the ellipsis left out."""
    return [t for t in sequence if t != ELLIPSIS]


#: the panels of Fig 5 (phase portraits) and Fig 6 (spectra): w -> the paper's pattern
PAPER_FIG5 = {0.48: "1-0-0", 0.569: "grazing", 0.86: "1-1-0", 1.02: "2-2-0", 1.072: "grazing",
              1.25: "2-1-0", 1.37: "4-3-0", 1.384: "8-6-0", 1.53: "chaotic", 1.7: "4-3-0",
              1.81: "2-2-0", 2.24: "1-1-0"}
PAPER_FIG6 = {0.48: "1-0-0", 1.02: "2-2-0", 1.37: "4-3-0", 1.53: "chaotic"}
#: Figs 9-11: three coexisting double-sided motions (n-p-q) at one point
COEXIST_POINT = {"b": 0.15, "w": 0.82}
PAPER_FIG9_11 = {9: "1-1-1", 10: "2-2-1", 11: "4-4-2"}
PAPER_COEXIST = tuple(PAPER_FIG9_11.values())

#: the tolerances of a comparison with the paper: w of a landmark, a threshold, DC at the jump
LANDMARK_TOL = 0.02
THRESHOLD_TOL = 0.01
JUMP_DC_TOL = 0.03


def within(difference: float, tolerance: float) -> bool:
    """Whether a difference from the paper is within the tolerance (grid midpoints such as
    1.31 - 1.33 carry rounding of 1e-16: a difference of exactly the tolerance counts)."""
    return bool(math.isfinite(difference) and round(abs(difference), 9) <= tolerance)
