"""The calibration's sweeps and what is read off them: the w grid and integration
(:class:`SweepSettings`), the one sweep builder (:func:`w_sweep`, on
:func:`gearsim.cell.sweep.sweep_records`), and the two thresholds: backlash (back contact) and
damping (subharmonics), each by :func:`gearsim.calibration.search.bisect_bool`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from gearsim.calibration.search import bisect_bool
from gearsim.cell.motion import double_sided
from gearsim.cell.sweep import sweep_records, sweep_records_many
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.settings import IntegrationSettings, Method
from gearsim.study.config import Study

#: the integration of every calibration sweep: DP5 at rtol 1e-7 and 40 periods of transient on
#: continuation (16 flips 1T/2T next to a period doubling). Every field that decides a result is
#: given, so the calibration's recorded numbers do not move with the cell defaults.
CALIBRATION_SIM = IntegrationSettings(
    method="dp5", rtol=1e-7, atol=1e-12, hmax=0.2, steps_per_period=256, transient=150,
    transient_continuation=40, chunk=32, max_periods=256, n_max=64, period_rtol=1e-5,
    lyap_threshold=0.005, divergence_bound=1.0e6, tangent_lead=24, max_steps=5_000_000,
    transient_recurrence=0)

#: the paper's plane grid in w: 400 cell centres on [0.1, 2.5] (the backlash thresholds' grid)
PLANE_W_GRID = 0.1 + (np.arange(400) + 0.5) * 2.4 / 400
#: the thresholds' default grid: 241 points on [0.1, 2.5]
THRESHOLD_W_GRID = np.linspace(0.1, 2.5, 241)


@dataclass(frozen=True)
class SweepSettings:
    """The w grid and the integration of the calibration sweeps: the one definition that the
    landmark objective (:class:`gearsim.calibration.calibrate.ObjectiveSettings`) and the forms'
    measurement (:class:`gearsim.calibration.fidelity.FidelitySettings`) share."""

    w_min: float = 0.3
    w_max: float = 2.5
    dw: float = 0.01
    sim: IntegrationSettings = CALIBRATION_SIM
    Fm: float = 0.1  # scale of the search (the shape is scale-free; Fm is derived afterwards)
    b0: float = 1.0  # backlash of the search scale (above the backlash threshold)
    xi_w_min: float = 0.6
    xi_dw: float = 0.03
    #: sweeps as continuation chains in the batched kernel's lanes with the study's RK4
    #: settings (:attr:`gearsim.study.config.Study.settings`) instead of ``sim``
    lanes: bool = False
    #: the study whose standard parameters and RK4 settings a fit uses (:meth:`with_study`)
    study: Study | None = field(default=None, repr=False, compare=False)

    def grid(self, dw: float | None = None, lo: float | None = None, hi: float | None = None
             ) -> np.ndarray:
        """Cell centres of ``[lo, hi]`` (default ``[w_min, w_max]``) at step about ``dw``."""
        lo = self.w_min if lo is None else lo
        hi = self.w_max if hi is None else hi
        dw = self.dw if dw is None else dw
        n = int(round((hi - lo) / dw))
        return lo + (np.arange(n) + 0.5) * (hi - lo) / n

    def with_study(self, study: Study) -> SweepSettings:
        """These settings for ``study``: its standard parameters are a form's base
        (:meth:`gearsim.calibration.forms.Form.params`), its RK4 settings the lanes'."""
        return replace(self, study=study)

    def the_study(self) -> Study:
        """The study these settings were given (:meth:`with_study`)."""
        if self.study is None:
            raise ValueError("calibration settings without a study: give it with .with_study()")
        return self.study

    def integration(self) -> IntegrationSettings:
        if self.lanes:
            return self.the_study().settings
        return self.sim

    def to_dict(self) -> dict[str, Any]:
        """The settings as recorded with a result (the study by its integration only)."""
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "study"}
        d = {k: asdict(v) if is_dataclass(v) else v for k, v in d.items()}
        if self.lanes:
            d["sim"] = asdict(self.integration())
        return d


def w_sweep(params: ModelParameters, grid: np.ndarray, settings: IntegrationSettings | None = None,
            *, continuation: bool = True, w_factor: float = 1.0) -> pd.DataFrame:
    """Forward w sweep over ``grid`` (:func:`gearsim.cell.sweep.sweep_records`;
    ``continuation``: each cell starts from the previous steady state, otherwise every cell
    from the same static state, the paper's fixed-start method).

    ``w_factor``: the frequency-scale mapping (``r = w_c / w_n`` when the paper's axis is the
    coupled mesh mode, :func:`gearsim.dynamics.parameters.mesh_mode_ratio`): ``grid`` is the
    paper's axis, the cells are simulated at ``w = r * grid`` (column ``w_sim``) and ``value`` is
    the axis value."""
    grid = np.sort(np.asarray(grid, dtype=float))
    rows = sweep_records(params, "w", grid * w_factor, continuation=continuation,
                         settings=settings)
    df = pd.DataFrame(rows)
    df["w_sim"] = df["value"]
    df["value"] = grid
    return df


def w_sweeps(specs: Sequence[tuple[ModelParameters, np.ndarray, float]],
             settings: IntegrationSettings, *, continuation: bool = True) -> list[pd.DataFrame]:
    """Many :func:`w_sweep` at once: ``specs[k] = (params, grid, w_factor)``. RK4 ``settings``:
    every sweep is one chain of one batched-kernel call
    (:func:`gearsim.cell.sweep.sweep_records_many`); otherwise scalar sweeps one by one."""
    if settings.method is not Method.RK4:
        return [w_sweep(p, g, settings, continuation=continuation, w_factor=wf)
                for p, g, wf in specs]
    grids = [np.sort(np.asarray(g, dtype=float)) for _p, g, _wf in specs]
    recs = sweep_records_many([(p, g * wf) for (p, _g, wf), g in zip(specs, grids, strict=True)],
                              "w", settings=settings, continuation=continuation)
    out = []
    for g, rows in zip(grids, recs, strict=True):
        df = pd.DataFrame(rows)
        if len(df):
            df["w_sim"] = df["value"]
            df["value"] = g
        out.append(df)
    return out


def has_subharmonics(df: pd.DataFrame) -> bool:
    """Whether a sweep holds any motion other than period 1 (0/1T, 1/1T)."""
    periodic1 = (df["motion"] == "periodic") & (df["n"] == 1)
    return bool((~periodic1).any())


def has_back_contact(df: pd.DataFrame) -> bool:
    """Whether any cell of a sweep impacts double-sided
    (:func:`gearsim.cell.motion.double_sided`)."""
    return bool(double_sided(df["I"], df["q"]).any())


def double_sided_anywhere(params: ModelParameters, grid: np.ndarray,
                          settings: IntegrationSettings, **sweep_kw: Any) -> bool:
    """Whether a forward sweep over ``grid`` (:func:`w_sweep` with ``sweep_kw``) shows any back
    impact."""
    return has_back_contact(w_sweep(params, grid, settings, **sweep_kw))


def backlash_from_sweep(df: pd.DataFrame, b0: float) -> float:
    """Backlash threshold from one forward sweep run at backlash ``b0`` without back contact.

    Without back contact the motion in ``x - b`` does not depend on ``b``; back contact starts
    where ``x < -b``, i.e. ``x - b0 < -2 b``. So every ``b > (b0 - min x) / 2`` leaves the sweep
    unchanged and free of back contact, and smaller ``b`` brings it at the cell of the minimum:
    ``b* = (b0 - min_w x_min) / 2`` on this grid. NaN if the sweep has back contact at ``b0``.
    """
    if has_back_contact(df):
        return math.nan
    xmin = df["x_min"].to_numpy(dtype=float)
    xmin = xmin[np.isfinite(xmin)]
    if not len(xmin):
        return math.nan
    return float((b0 - xmin.min()) / 2.0)


def backlash_threshold(
    params: ModelParameters,
    *,
    grid: np.ndarray | None = None,
    settings: IntegrationSettings | None = None,
    lo: float = 0.0,
    hi: float | None = None,
    tol: float = 0.002,
    **sweep_kw: Any,
) -> float:
    """Smallest ``b`` above which no double-sided impact occurs over ``grid`` (bisection of
    whole sweeps, :func:`w_sweep` with ``sweep_kw``); ``inf`` if there is one at ``hi``.

    Assumes monotonicity in ``b`` (checked at the bracket ends). ``hi`` defaults to
    ``10 (Fm + Fe)`` which is far above the motion amplitude.
    """
    grid = THRESHOLD_W_GRID if grid is None else grid
    settings = settings or CALIBRATION_SIM
    hi = 10.0 * (params.Fm + params.Fe) if hi is None else hi

    def double(b: float) -> bool:
        return double_sided_anywhere(params.with_(b=b), grid, settings, **sweep_kw)

    if double(hi):
        return float("inf")
    if lo > 0 and not double(lo):
        return lo
    return bisect_bool(double, lo, hi, tol)


def damping_threshold(
    params: ModelParameters,
    *,
    grid: np.ndarray | None = None,
    settings: IntegrationSettings | None = None,
    lo: float = 0.04,
    hi: float = 0.3,
    tol: float = 0.001,
) -> float:
    """Smallest ``xi`` above which only period-1 motion (0/1T, 1/1T) remains (bisection)."""
    grid = THRESHOLD_W_GRID if grid is None else grid
    settings = settings or CALIBRATION_SIM

    def sub(x):
        return has_subharmonics(w_sweep(params.with_(xi=x), grid, settings))

    if sub(hi):
        return float("inf")
    if not sub(lo):
        return lo
    return bisect_bool(sub, lo, hi, tol)
