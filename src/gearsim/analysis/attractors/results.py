"""What the finder returns: the steady motion of a start, a cell's attractors, their summary."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

FOUND_BY = ("forward", "backward", "start")


@dataclass
class Steady:
    """The classified steady motion reached from one state (a system's full-length run).

    ``period`` is the motion period in forcing periods (0: none found, e.g. chaos);
    ``points`` the section states of the analysed window (``(m, d)``, at least ``(x, x')``);
    ``scale_x`` and ``scale_v`` the displacement and velocity ranges of the motion that set
    the matching tolerances (system units); ``info`` the classification record.
    """

    status: str  # "ok", "unsettled" (no steady motion within the budget) or "diverged"
    period: int
    points: np.ndarray
    scale_x: float
    scale_v: float
    label: str
    info: dict[str, Any] = field(default_factory=dict)
    final_state: np.ndarray | None = None




@dataclass
class Attractor:
    """One attractor of a cell: its steady motion, basin fraction and who found it."""

    index: int
    steady: Steady
    n_starts: int  # random starts that reach it
    basin_fraction: float  # n_starts / K
    found_by: tuple[str, ...]  # subset of FOUND_BY, in that order
    n_early: int = 0  # of n_starts, labelled early (certified ellipsoid or recurrence)

    @property
    def label(self) -> str:
        return self.steady.label

    @property
    def points(self) -> np.ndarray:
        return self.steady.points

    def record(self) -> dict[str, Any]:
        """Flat record (the catalogue's ``attractors`` columns, plus the classification)."""
        r = dict(self.steady.info)
        r.update(
            attractor=self.index,
            label=self.steady.label,
            n=int(self.steady.period),
            basin_fraction=float(self.basin_fraction),
            n_starts=int(self.n_starts),
            n_early=int(self.n_early),
            found_by=",".join(self.found_by),
            poincare_x=self.steady.points[:, 0].tolist(),
            poincare_v=self.steady.points[:, 1].tolist(),
        )
        return r


@dataclass
class CellAttractors:
    """All attractors of one cell and the fate of every start.

    ``start_labels[i]`` is the attractor index reached from random start ``i`` (-1: diverged);
    ``early[i]`` whether it was labelled by recurrence; ``start_periods_run[i]`` the forcing
    periods integrated for it; ``continuation[name]`` the attractor index reached from the
    ``forward`` / ``backward`` state (-1 diverged).
    """

    attractors: list[Attractor]
    starts: np.ndarray  # (K, d) start states
    start_labels: np.ndarray  # (K,)
    early: np.ndarray  # (K,) bool
    start_periods_run: np.ndarray  # (K,)
    continuation: dict[str, int]

    @property
    def n_starts(self) -> int:
        return len(self.start_labels)

    @property
    def diverged_fraction(self) -> float:
        k = len(self.start_labels)
        return float(np.sum(self.start_labels < 0) / k) if k else 0.0

    def records(self) -> list[dict[str, Any]]:
        return [a.record() for a in self.attractors]



def n_real(ca: CellAttractors) -> int:
    """Number of attractors of a cell (the ``unsettled`` bucket does not count)."""
    return sum(1 for a in ca.attractors if a.steady.status != "unsettled")


def summary_lines(ca: CellAttractors) -> list[str]:
    """Human-readable lines: one per attractor, then the divergent share."""
    lines = []
    nan = float("nan")
    for a in ca.attractors:
        i = a.steady.info
        npq = i.get("label_npq") or ""
        pat = f"{a.label} ({npq})" if npq else a.label
        mu = i.get("mu_max", nan)
        verified = (f" |mu|max={mu:.5f} ({i.get('critical')})" if mu == mu else "") + (
            f" status={i.get('status')}" if i.get("status", "ok") != "ok" else "")
        lines.append(
            f"#{a.index} {pat:<18} basin={a.basin_fraction:6.3f} ({a.n_starts}/{ca.n_starts} "
            f"starts, {a.n_early} early) I={i.get('I')} DC={i.get('dc', nan):.4f} "
            f"Kmax={i.get('kmax', nan):.4f} lyapunov={i.get('lyapunov', nan):+.4f} "
            f"found_by={','.join(a.found_by)}{verified}"
        )
    nd = int(np.sum(ca.start_labels < 0))
    lines.append(f"diverged: {nd}/{ca.n_starts} starts ({ca.diverged_fraction:.3f})")
    return lines


