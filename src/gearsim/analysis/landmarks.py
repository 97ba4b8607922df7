"""Landmarks of a one-parameter orbit diagram: grazings, jumps, period doublings, chaos.

Input is the DataFrame of :func:`gearsim.cell.sweep.orbit_diagram` (one row per parameter value with
the columns ``value, motion, I, n, p, q, label, label_npq, dc, kmax*``; ``poincare_x`` is not
needed). Output is a tidy DataFrame, one row per landmark, that the figures annotate (``G Bif``,
``PD Bif``, ``Jump``) and the report compares with the paper.

Landmark kinds (:data:`KINDS`), each located *between* two neighbouring grid values ``lo`` and
``hi`` (``value`` is their midpoint unless refined by :func:`refine_landmarks`):

``grazing``
    Impact state I 0 -> 1 at period 1 (``1-0-0 -> 1-1-0``), or at a fixed period ``n`` a change of
    the impact counts p / q (``2-2-0 -> 2-1-0``, ``4-2-0 -> 4-3-0``). Also I 1 -> 0 (``exit``
    grazing, ``direction = -1``).
``jump``
    A discontinuity of the disengagement duty cycle: ``|DC_hi - DC_lo| >= jump_dc`` with the same
    pattern on both sides or a pattern change that is not a period doubling.
``period_doubling``
    ``n -> 2 n`` between periodic cells.
``inverse_period_doubling``
    ``2 n -> n`` between periodic cells, and ``chaos -> n`` at the final exit from chaos (from the
    last chaos cell to the first periodic cell after it, across any quasi-periodic cells).
``chaos_onset``
    The first periodic -> chaos transition (chaos must persist ``min_chaos_run`` cells); a run of
    quasi-periodic / unsettled cells between the last periodic cell and the chaos belongs to the
    route into chaos (the onset is placed at its start).
``period_one``
    The last entry into period 1: from there on the motion stays ``n = 1`` (return to period 1).
``other``
    Any remaining pattern change (e.g. ``1 -> 3``), so nothing is silently lost.

Isolated ``quasi-periodic`` / ``unsettled`` cells (runs up to ``bridge`` cells long, flanked by
periodic cells) are classifier indecision next to a bifurcation, not dynamics: by default they are
bridged, and the landmark spans the whole gap (``lo`` and ``hi`` are the flanking periodic
cells). Set ``bridge=0`` to keep them.

The paper's landmark table for the standard sweep is
:data:`gearsim.analysis.paper.PAPER_LANDMARKS`;
:func:`match_paper` pairs it with the extracted landmarks in sweep order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.paper import PAPER_LANDMARKS, PaperLandmark

KINDS = (
    "grazing",
    "jump",
    "period_doubling",
    "inverse_period_doubling",
    "chaos_onset",
    "period_one",
    "other",
)

#: short annotations for figures
SHORT = {
    "grazing": "G Bif",
    "jump": "Jump",
    "period_doubling": "PD Bif",
    "inverse_period_doubling": "PD Bif",
    "chaos_onset": "Chaos",
    "period_one": "PD Bif",
    "other": "",
}

COLUMNS = (
    "kind",
    "value",
    "lo",
    "hi",
    "i_lo",
    "i_hi",
    "from_label",
    "to_label",
    "from_npq",
    "to_npq",
    "n_from",
    "n_to",
    "direction",
    "dc_lo",
    "dc_hi",
    "kmax_lo",
    "kmax_hi",
    "refined",
    "annotation",
)

_NONPERIODIC_BRIDGEABLE = ("quasi-periodic", "unsettled")


# ---------------------------------------------------------------------------- extraction
def _state(row: pd.Series) -> str:
    motion = row.get("motion", "periodic")
    if motion == "periodic" and int(row.get("n", 0) or 0) > 0:
        return str(row["label_npq"]) if row.get("label_npq") else f"{int(row['n'])}"
    return str(motion)


def _kmax_col(df: pd.DataFrame, kmax: str) -> np.ndarray:
    if kmax in df.columns:
        return df[kmax].to_numpy(dtype=float)
    return np.full(len(df), np.nan)


def _bridged_indices(states: list[str], motions: list[str], bridge: int) -> list[int]:
    """Indices of rows kept after bridging short non-periodic runs between periodic cells."""
    keep = []
    i = 0
    m = len(states)
    while i < m:
        if motions[i] in _NONPERIODIC_BRIDGEABLE and bridge > 0:
            j = i
            while j < m and motions[j] in _NONPERIODIC_BRIDGEABLE:
                j += 1
            run = j - i
            flanked = i > 0 and j < m and motions[i - 1] == "periodic" and motions[j] == "periodic"
            if run <= bridge and flanked:
                i = j
                continue
            keep.extend(range(i, j))
            i = j
            continue
        keep.append(i)
        i += 1
    return keep


@dataclass(frozen=True)
class _Cells:
    """The columns of a sweep's cells that the landmarks read, in sweep order."""

    frame: pd.DataFrame
    states: list[str]
    motions: list[str]
    values: np.ndarray
    dcs: np.ndarray
    km: np.ndarray
    ns: np.ndarray
    Is: np.ndarray
    labels: list[str]

    @classmethod
    def of(cls, df: pd.DataFrame, kmax: str) -> _Cells:
        d = df.reset_index(drop=True)
        if "motion" not in d.columns:
            d = d.assign(motion=np.where(d["n"].fillna(0).astype(int) > 0, "periodic", "chaos"))
        states = [_state(r) for _, r in d.iterrows()]
        return cls(
            frame=d,
            states=states,
            motions=[str(m) for m in d["motion"]],
            values=d["value"].to_numpy(dtype=float),
            dcs=d["dc"].to_numpy(dtype=float) if "dc" in d.columns else np.full(len(d), np.nan),
            km=_kmax_col(d, kmax),
            ns=d["n"].fillna(0).astype(int).to_numpy(),
            Is=(d["I"].fillna(0).astype(int).to_numpy() if "I" in d.columns
                else np.zeros(len(d), int)),
            labels=[str(x) for x in d["label"]] if "label" in d.columns else states,
        )

    def impacts(self, i: int) -> int:
        """``p + q`` of cell ``i``."""
        return int(self.frame.at[i, "p"] or 0) + int(self.frame.at[i, "q"] or 0)

    def row(self, kind: str, a: int, b: int, direction: float = 0) -> dict[str, Any]:
        """The landmark ``kind`` between cells ``a`` and ``b``."""
        values = self.values
        return {
            "kind": kind,
            "value": 0.5 * (values[a] + values[b]),
            "lo": float(values[a]),
            "hi": float(values[b]),
            "i_lo": int(a),
            "i_hi": int(b),
            "from_label": self.labels[a],
            "to_label": self.labels[b],
            "from_npq": self.states[a],
            "to_npq": self.states[b],
            "n_from": int(self.ns[a]) if self.motions[a] == "periodic" else 0,
            "n_to": int(self.ns[b]) if self.motions[b] == "periodic" else 0,
            "direction": int(direction),
            "dc_lo": float(self.dcs[a]),
            "dc_hi": float(self.dcs[b]),
            "kmax_lo": float(self.km[a]),
            "kmax_hi": float(self.km[b]),
            "refined": False,
            "annotation": SHORT[kind],
        }


def _band_ends(c: _Cells, keep: list[int]) -> tuple[int | None, int | None, int | None]:
    """The last chaos cell, the first periodic cell after it (the final exit from the chaotic
    band; quasi-periodic / unsettled cells between them belong to the route out of chaos) and
    the last entry into period 1 that is never left again (among the kept cells)."""
    motions, ns = c.motions, c.ns
    chaos_idx = [i for i in keep if motions[i] == "chaos"]
    last_chaos = chaos_idx[-1] if chaos_idx else None
    exit_to = None
    if last_chaos is not None:
        exit_to = next((i for i in keep if i > last_chaos and motions[i] == "periodic"), None)
    last_n1_entry = None
    if keep and motions[keep[-1]] == "periodic" and ns[keep[-1]] == 1:
        k = len(keep) - 1
        while k > 0 and motions[keep[k - 1]] == "periodic" and ns[keep[k - 1]] == 1:
            k -= 1
        if k > 0:
            last_n1_entry = keep[k]
    return last_chaos, exit_to, last_n1_entry


def _periodic_pair(c: _Cells, a: int, b: int, ddc: float, is_jump: bool,
                   last_n1_entry: int | None) -> list[tuple[str, int, int, float]]:
    """The landmarks between two neighbouring periodic cells of different states."""
    na, nb = c.ns[a], c.ns[b]
    out: list[tuple[str, int, int, float]] = []
    if nb == 2 * na:
        out.append(("period_doubling", a, b, 0))
    elif na == 2 * nb:
        if nb == 1 and b == last_n1_entry:
            out.append(("period_one", a, b, 0))
        else:
            out.append(("inverse_period_doubling", a, b, 0))
    elif na == nb:
        pa, pb = c.impacts(a), c.impacts(b)
        if is_jump and (c.Is[a] == c.Is[b]):
            out.append(("jump", a, b, np.sign(ddc)))
        else:
            out.append(("grazing", a, b, 1 if (c.Is[b] > c.Is[a] or pb > pa) else -1))
            if is_jump:
                out.append(("jump", a, b, np.sign(ddc)))
    else:
        if nb == 1 and b == last_n1_entry:
            out.append(("period_one", a, b, 0))
        else:
            out.append(("other", a, b, 0))
        if is_jump:
            out.append(("jump", a, b, np.sign(ddc)))
    return out


def _chaos_run(c: _Cells, keep: list[int], b: int) -> int:
    """Chaos cells in a row from kept cell ``b`` on (after quasi-periodic / unsettled ones)."""
    run = 0
    entered = False
    for k in keep[keep.index(b) :]:
        if c.motions[k] in _NONPERIODIC_BRIDGEABLE and not entered:
            continue
        if c.motions[k] != "chaos":
            break
        entered = True
        run += 1
    return run


def find_landmarks(
    df: pd.DataFrame,
    *,
    jump_dc: float = 0.15,
    bridge: int = 2,
    min_chaos_run: int = 2,
    kmax: str = "kmax_peak_static",
) -> pd.DataFrame:
    """Extract the landmarks of an orbit diagram.

    Parameters
    ----------
    df
        Output of :func:`gearsim.cell.sweep.orbit_diagram` (any sweep direction; rows are sorted by
        ``value`` in the order swept, so a backward sweep yields landmarks in decreasing value).
    jump_dc
        Smallest DC step between neighbouring cells that counts as a jump.
    bridge
        Longest run of quasi-periodic / unsettled cells between periodic cells that is treated
        as classifier indecision and bridged (0 keeps every cell).
    min_chaos_run
        Cells of chaos needed after a periodic cell for ``chaos_onset``.
    kmax
        Column used for ``kmax_lo`` / ``kmax_hi``.

    Returns
    -------
    DataFrame with columns :data:`COLUMNS`, one row per landmark in sweep order. ``value`` is
    the midpoint of ``lo`` and ``hi`` (the neighbouring grid values); ``direction`` is +1 for
    I 0 -> 1 or increasing p (+q), -1 otherwise (grazings), and the sign of the DC step (jumps).
    """
    if len(df) == 0:
        return pd.DataFrame(columns=list(COLUMNS))
    c = _Cells.of(df, kmax)
    states, motions, dcs, ns = c.states, c.motions, c.dcs, c.ns
    keep = _bridged_indices(states, motions, bridge)
    last_chaos, exit_to, last_n1_entry = _band_ends(c, keep)

    rows: list[dict[str, Any]] = []
    onset_done = False
    in_onset = False

    def add(kind, a, b, direction=0):
        rows.append(c.row(kind, a, b, direction))

    for a, b in zip(keep[:-1], keep[1:], strict=True):
        sa, sb = states[a], states[b]
        ma, mb = motions[a], motions[b]
        ddc = dcs[b] - dcs[a]
        is_jump = math.isfinite(ddc) and abs(ddc) >= jump_dc
        if sa == sb:
            if is_jump:
                add("jump", a, b, np.sign(ddc))
            continue
        if ma == "periodic" and mb == "periodic":
            for landmark in _periodic_pair(c, a, b, ddc, is_jump, last_n1_entry):
                add(*landmark)
            continue
        if ma == "periodic" and (mb == "chaos" or mb in _NONPERIODIC_BRIDGEABLE):
            # chaos onset: periodic -> chaos, possibly through quasi-periodic / unsettled cells
            if not onset_done and _chaos_run(c, keep, b) >= min_chaos_run:
                add("chaos_onset", a, b)
                onset_done = True
                in_onset = True
            else:
                add("other", a, b)
            continue
        if in_onset and ma in _NONPERIODIC_BRIDGEABLE and mb in ("chaos",) + \
                _NONPERIODIC_BRIDGEABLE:
            continue  # inside the route to chaos already marked by chaos_onset
        in_onset = False
        if last_chaos is not None and last_chaos <= a and exit_to is not None and b < exit_to:
            continue  # chaos -> quasi-periodic on the way out: part of the exit below
        if ma != "periodic" and mb == "periodic" and b == exit_to:
            add("period_one" if (ns[b] == 1 and b == last_n1_entry) else
                "inverse_period_doubling", last_chaos, b)
            continue
        if ma == "chaos" and mb == "periodic":
            if a == last_chaos:
                add("period_one" if (ns[b] == 1 and b == last_n1_entry) else
                    "inverse_period_doubling", a, b)
            else:
                add("other", a, b)
            continue
        add("other", a, b)
    out = pd.DataFrame(rows, columns=list(COLUMNS))
    return out


# ---------------------------------------------------------------------------- paper matching
def _matches(pl: PaperLandmark, lm: pd.Series) -> bool:
    kind = lm["kind"]
    fr = lm["from_npq"]
    if pl.kind == "grazing":
        if kind != "grazing":
            return False
        n_pl = int(pl.from_npq.split("-")[0])
        if lm["n_from"] != n_pl or lm["n_to"] != n_pl:
            return False
        if pl.key == "grazing_1":
            return fr.endswith("-0-0") and lm["direction"] > 0
        # p changes in the paper's direction
        p_from, p_to = int(pl.from_npq.split("-")[1]), int(pl.to_npq.split("-")[1])
        return int(lm["direction"]) == (1 if p_to > p_from else -1)
    if pl.kind == "jump":
        return kind == "jump" and lm["direction"] > 0
    if pl.kind == "period_doubling":
        n_to = int(pl.to_npq.split("-")[0])
        return kind == "period_doubling" and lm["n_to"] == n_to
    if pl.kind == "chaos_onset":
        return kind == "chaos_onset"
    if pl.kind == "inverse_period_doubling":
        n_to = int(pl.to_npq.split("-")[0])
        if pl.from_npq == "chaos":
            return fr == "chaos" and kind in ("inverse_period_doubling", "period_one")
        return kind == "inverse_period_doubling" and lm["n_to"] == n_to and lm["n_from"] == 2 * n_to
    if pl.kind == "period_one":
        return kind == "period_one"
    return False


def match_paper(
    landmarks: pd.DataFrame,
    paper: Sequence[PaperLandmark] = PAPER_LANDMARKS,
) -> pd.DataFrame:
    """Pair the paper's landmarks with extracted ones, in sweep order.

    Each paper landmark takes the first extracted landmark of the same kind (and the same
    period change / impact-count direction) that lies after the previously matched one; a paper
    landmark with no partner is reported as missing (``ours`` NaN). Pattern names are compared
    by kind and period, not by exact ``n-p-q`` (``exact_pattern`` says whether they agree).

    Returns
    -------
    DataFrame: ``key, kind, text, paper, paper_lo, paper_hi, ours, lo, hi, error, found,
    exact_pattern, ours_from, ours_to``.
    """
    rows = []
    pos = 0
    lms = landmarks.reset_index(drop=True)
    for pl in paper:
        hit = None
        for j in range(pos, len(lms)):
            if _matches(pl, lms.loc[j]):
                hit = j
                break
        row: dict[str, Any] = {
            "key": pl.key,
            "kind": pl.kind,
            "text": pl.text,
            "paper": pl.w,
            "paper_lo": pl.w_range[0],
            "paper_hi": pl.w_range[1],
        }
        if hit is None:
            row.update(ours=float("nan"), lo=float("nan"), hi=float("nan"), error=float("nan"),
                       found=False, exact_pattern=False, ours_from="", ours_to="")
        else:
            lm = lms.loc[hit]
            to_ok = pl.to_npq in (None, lm["to_npq"]) or (
                pl.to_npq == "chaos" and lm["to_npq"] in ("quasi-periodic", "unsettled"))
            exact = (pl.from_npq in (None, lm["from_npq"])) and to_ok
            row.update(ours=float(lm["value"]), lo=float(lm["lo"]), hi=float(lm["hi"]),
                       error=pl.error(float(lm["value"])), found=True, exact_pattern=bool(exact),
                       ours_from=lm["from_npq"], ours_to=lm["to_npq"])
            pos = hit + 1
        rows.append(row)
    return pd.DataFrame(rows)


def pattern_sequence(df: pd.DataFrame, *, bridge: int = 2, use_npq: bool = False) -> list[str]:
    """The sequence of distinct patterns along a sweep (``I/nT`` labels, or ``n-p-q``).

    Short runs of quasi-periodic / unsettled cells are bridged as in :func:`find_landmarks`;
    consecutive duplicates are merged.
    """
    if len(df) == 0:
        return []
    d = df.reset_index(drop=True)
    states = [_state(r) for _, r in d.iterrows()]
    motions = [str(m) for m in d["motion"]]
    keep = _bridged_indices(states, motions, bridge)
    seq: list[str] = []
    for i in keep:
        if motions[i] == "periodic":
            lab = states[i] if use_npq else str(d.at[i, "label"])
        else:
            lab = motions[i]
        if not seq or seq[-1] != lab:
            seq.append(lab)
    return seq


def is_subsequence(expected: Sequence[str], seq: Sequence[str]) -> bool:
    """Whether ``expected`` appears in ``seq`` in order (other patterns may lie between)."""
    it = iter(seq)
    return all(any(x == y for y in it) for x in expected)
