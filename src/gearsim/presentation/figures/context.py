"""What a figure builder reads and the notes the builders share: :class:`Context` (the tables by
their config names, the parameters and integration settings), :class:`Built` (a drawn figure
with our caption and where we differ from the paper), the figures' own point settings, and the
paper's thresholds beside ours for a plane of any axes."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from gearsim.analysis.paper import (
    PAPER_B_THRESHOLD,
    PAPER_XI_THRESHOLD,
)
from gearsim.cell.motion import double_sided
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError
from gearsim.study.config import IntegrationSettings  # the configuration's integration section
from gearsim.study.figure_tables import POINT_TRANSIENT, POINT_TRANSIENT_CONTINUATION


@dataclass
class Context:
    """What the figures read. Tables are looked up by their config names."""

    params: ModelParameters = field(default_factory=ModelParameters)
    settings: IntegrationSettings = field(default_factory=IntegrationSettings)
    sweeps: dict[str, pd.DataFrame] = field(default_factory=dict)
    planes: dict[str, pd.DataFrame] = field(default_factory=dict)
    points: dict[str, pd.DataFrame] = field(default_factory=dict)  # pipeline point tables
    point_specs: dict[str, Any] = field(default_factory=dict)  # config `points:`
    sweep_fixed: dict[str, dict[str, float]] = field(default_factory=dict)  # config `sweeps:`
    # continuation tables (docs/orbits.md): "standard" (branches of the standard sweep's set),
    # "standard_points", "<plane>_curves" (two-parameter bifurcation curves)
    orbits: dict[str, pd.DataFrame] = field(default_factory=dict)
    # what the figures draw that is simulated (gearsim.study.figure_data): "fig2", "fig9_11",
    # "fig19", "fig20"; what each table states beside its rows is its attrs["figure_data"]
    figure_data: dict[str, pd.DataFrame] = field(default_factory=dict)


@dataclass
class Built:
    number: int
    figure: Any  # matplotlib Figure
    caption: str  # ours
    differences: list[str]
    inputs: list[str] = field(default_factory=list)


def sweep_title(name: str, fixed: dict[str, float] | None = None) -> str:
    """``b = 0.15`` from a sweep's fixed parameters, or from a name like ``b015`` / ``xi005``."""
    sym = {"b": "b", "xi": "ξ", "w": "ω", "eps": "ε"}
    if fixed:
        return ", ".join(f"{sym.get(k, k)} = {v:g}" for k, v in fixed.items())
    m = re.fullmatch(r"([a-z]+)0(\d+)", name)
    if m:
        return f"{sym.get(m.group(1), m.group(1))} = 0.{m.group(2)}"
    return name


_POINT_NOTE = (f"The figure's own simulations use at least {POINT_TRANSIENT} transient periods "
               f"({POINT_TRANSIENT_CONTINUATION} when continued), more than the plane cells, so "
               "slowly decaying transients are not drawn as long-period motions.")


def _need(table: dict[str, pd.DataFrame], name: str, kind: str) -> pd.DataFrame:
    if name not in table:
        raise UsageError(f"this figure needs the {kind} '{name}' (pass --{kind} {name}=PATH)")
    return table[name]


def _sweep_note(df: pd.DataFrame) -> str:
    v = df["value"].to_numpy(dtype=float)
    step = (v.max() - v.min()) / max(len(v) - 1, 1) if len(v) else float("nan")
    return (f"{len(v)} swept values of ω (step {step:.4f}; the study's config uses 1201, the "
            "paper does not state its step); landmarks are located to within one step; "
            "pattern sequences leave out runs shorter than 3 swept values")


def _grid_note(df: pd.DataFrame) -> str:
    nx, ny = int(df["i"].max()) + 1, int(df["j"].max()) + 1
    paper = " (paper 400 x 400)" if _axes(df) in (("w", "b"), ("w", "xi")) else ""
    return f"grid {nx} x {ny} cells{paper}"


def _axes(df: pd.DataFrame) -> tuple[str, str]:
    from gearsim.presentation.figures.data import plane_axes

    return plane_axes(df)


def axes_text(df: pd.DataFrame) -> str:
    """``(ω, b)``: the plane's two axes, as the paper writes them."""
    sym = {"b": "b", "xi": "ξ", "w": "ω", "eps": "ε"}
    x, y = _axes(df)
    return f"({sym.get(x, x)}, {sym.get(y, y)})"


def _threshold_b(df: pd.DataFrame) -> str:
    two = df[double_sided(df["I"], df.get("q"))]
    if not len(two):
        return "no double-sided cells (back impacts) in our (ω, b) plane"
    return (f"double-sided cells (back impacts) up to b = {float(two['b'].max()):.4f} in ours "
            f"(paper: only for b < {PAPER_B_THRESHOLD})")


def _threshold_xi(df: pd.DataFrame) -> str:
    other = df[~df["label"].isin(["0/1T", "1/1T"])]
    if not len(other):
        return "only 0/1T and 1/1T in our (ω, ξ) plane"
    return (f"patterns other than 0/1T and 1/1T up to ξ = {float(other['xi'].max()):.4f} in "
            f"ours (paper: only 0/1T and 1/1T for ξ > {PAPER_XI_THRESHOLD})")


def paper_comparison(df: pd.DataFrame) -> str:
    """The paper's threshold for a plane of these axes beside ours, or "not applicable" when
    the paper has no plane of these axes."""
    axes = _axes(df)
    if axes == ("w", "b"):
        return _threshold_b(df)
    if axes == ("w", "xi"):
        return _threshold_xi(df)
    return (f"Paper comparison not applicable: the paper has no {axes_text(df)} plane (it "
            "maps (ω, b) and (ω, ξ) only).")


def _plane(ctx: Context, plane: str) -> pd.DataFrame:
    return _need(ctx.planes, plane, "plane")
