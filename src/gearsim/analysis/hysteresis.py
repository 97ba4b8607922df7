"""The fold of a sweep run in both directions: where each direction jumps (hysteresis)."""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from gearsim.dynamics.parameters import ParameterError


@dataclass
class Hysteresis:
    """The fold of a pair of sweeps: where each direction jumps (parameter values).

    ``jump_forward`` is the value (midpoint of the two neighbouring grid values) where the
    sweep in increasing order jumps, ``jump_backward`` where the sweep in decreasing order jumps
    back; ``band`` is the interval between them (the hysteresis band: both motions coexist
    there). ``dc_*`` are the disengagement duty cycles on both sides of each jump; ``differ``
    lists the grid values where the two sweeps reach different motions (pattern or DC).
    """

    parameter: str
    jump_forward: float | None
    jump_backward: float | None
    dc_forward: tuple[float, float] | None
    dc_backward: tuple[float, float] | None
    differ: list[float]

    @property
    def band(self) -> tuple[float, float] | None:
        if self.jump_forward is None or self.jump_backward is None:
            return None
        return (min(self.jump_forward, self.jump_backward),
                max(self.jump_forward, self.jump_backward))  # fmt: skip

    def lines(self) -> list[str]:
        """Report lines (Markdown bullets)."""
        p = self.parameter
        if self.band is None:
            return [f"- no jump pair found in the {p} sweeps (forward jump {self.jump_forward}, "
                    f"backward jump {self.jump_backward})"]  # fmt: skip
        (a, b), (c, d) = self.dc_forward, self.dc_backward
        lo, hi = self.band
        return [
            f"- jump in the increasing-{p} sweep at {p} = {self.jump_forward:.4f} "
            f"(DC {a:.3f} -> {b:.3f})",
            f"- jump back in the decreasing-{p} sweep at {p} = {self.jump_backward:.4f} "
            f"(DC {c:.3f} -> {d:.3f})",
            f"- hysteresis band {lo:.4f} <= {p} <= {hi:.4f} (width {hi - lo:.4f}); the two "
            f"sweeps reach different motions at {len(self.differ)} grid values, "
            f"{sum(lo <= v <= hi for v in self.differ)} of them inside the band",
        ]


def _largest_jump(df: pd.DataFrame, jump_dc: float):
    from gearsim.analysis.landmarks import find_landmarks

    lms = find_landmarks(df.reset_index(drop=True), jump_dc=jump_dc)
    j = lms[lms["kind"] == "jump"]
    if not len(j):
        return None, None
    k = (j["dc_hi"] - j["dc_lo"]).abs().idxmax()
    r = j.loc[k]
    return float(r["value"]), (float(r["dc_lo"]), float(r["dc_hi"]))


def hysteresis(
    sweeps: pd.DataFrame, *, jump_dc: float = 0.15, dc_tol: float = 0.02
) -> Hysteresis:
    """Jump-up and jump-down values of the fold from a sweep run in both directions.

    ``sweeps``: rows of a ``direction: both`` sweep (or a forward and a backward sweep
    concatenated) with ``direction``, ``value``, ``label``, ``label_npq``, ``dc`` (the output
    of ``gearsim sweep``). Jumps are the largest DC discontinuity of each direction
    (:func:`gearsim.analysis.landmarks.find_landmarks`, ``jump_dc``). Two sweeps *differ* at a grid
    value when pattern (label, n-p-q) or DC (by more than ``dc_tol``) differ.
    """
    need = {"direction", "value", "label", "label_npq", "dc", "parameter"}
    if not need <= set(sweeps.columns):
        raise ParameterError(f"hysteresis: sweep table lacks {sorted(need - set(sweeps.columns))}")
    fwd = sweeps[sweeps["direction"] == "forward"].sort_values("value")
    bwd = sweeps[sweeps["direction"] == "backward"].sort_values("value", ascending=False)
    if not len(fwd) or not len(bwd):
        raise ParameterError("hysteresis: needs a forward and a backward sweep (direction: both)")
    jf, dcf = _largest_jump(fwd, jump_dc)
    jb, dcb = _largest_jump(bwd, jump_dc)
    a = fwd.set_index("value")[["label", "label_npq", "dc"]]
    b = bwd.set_index("value")[["label", "label_npq", "dc"]]
    common = a.index.intersection(b.index)
    differ = [float(v) for v in common
              if (a.loc[v, "label"], a.loc[v, "label_npq"])
              != (b.loc[v, "label"], b.loc[v, "label_npq"])
              or abs(float(a.loc[v, "dc"]) - float(b.loc[v, "dc"])) > dc_tol]  # fmt: skip
    return Hysteresis(str(fwd["parameter"].iloc[0]), jf, jb, dcf, dcb, sorted(differ))

