"""What the paper states that the report compares with (Liu et al., PLOS ONE 2025), and the
tolerances of the comparison. The landmarks of the standard sweep and the values at the jump
are in :mod:`gearsim.analysis.landmarks`."""

from __future__ import annotations

import math

NOT_APPLICABLE = "not applicable"
PAPER_B_THRESHOLD = 0.4125
PAPER_XI_THRESHOLD = 0.1436
LANDMARK_TOL = 0.02
THRESHOLD_TOL = 0.01
JUMP_DC_TOL = 0.03

#: Paper sequences (Sect 3.2 text of Fig 8, Sect 3.3 list of Fig 15). ``None`` = the paper gives
#: only a qualitative description (quoted in ``PAPER_SEQUENCE_TEXT``).
PAPER_SEQUENCES: dict[str, list[str] | None] = {
    "b015": ["0/1T", "1/1T", "2/1T", "2/2T", "1/2T", "1/1T"],
    "b025": None,
    "b035": None,
    "xi005": ["0/1T", "1/1T", "1/2T", "1/4T", "chaos", "1/8T", "1/4T", "1/2T", "1/1T"],
    "xi009": ["0/1T", "1/1T", "1/2T", "1/4T", "1/2T", "1/1T"],
    "xi015": ["0/1T", "1/1T"],
}
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
SEQUENCE_SWEEPS = {"b015": ("b", 0.15), "b025": ("b", 0.25), "b035": ("b", 0.35),
                   "xi005": ("xi", 0.05), "xi009": ("xi", 0.09), "xi015": ("xi", 0.15)}

#: what the paper has for a plane of these axes
PAPER_PLANES = {("w", "b"): "Figs 7, 12, 13 and the backlash threshold b = 0.4125",
                ("w", "xi"): "Figs 14, 16, 17 and the damping threshold xi = 0.1436"}


def within(difference: float, tolerance: float) -> bool:
    """Whether a difference from the paper is within the tolerance (grid midpoints such as
    1.31 - 1.33 carry rounding of 1e-16: a difference of exactly the tolerance counts)."""
    return bool(math.isfinite(difference) and round(abs(difference), 9) <= tolerance)

