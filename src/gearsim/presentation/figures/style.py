"""Shared look of the figures: colours of impact states and motion patterns, labels, saving.

Colours follow the paper's prose:

* bifurcation diagrams (Figs 4, 7a, 8, 14a, 15): red ``I = 0`` (no impact), black ``I = 1``
  (tooth-face impacts), blue ``I = 2`` (double-sided impacts); the two states the paper lists but
  never plots get their own colours (green ``I = -1`` back impacts only, magenta ``I = -2``
  complete disengagement);
* pattern maps (Figs 3, 7b, 14b): red ``0/1T``, yellow ``1/1T``, a distinct colour for each
  sub-harmonic ``1/nT`` and each double-sided ``2/nT``, dark grey for double-sided (``I = 2``)
  chaotic / quasi-periodic motion and light grey for face-impact (``I = 1``) chaotic /
  quasi-periodic motion (quasi-periodic cells are hatched so the two stay apart).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

# --- impact state I -> colour, legend text ---------------------------------------------------
IMPACT_COLOURS: dict[int, str] = {
    0: "#d62728",  # red
    1: "#000000",  # black
    2: "#1f4fd6",  # blue
    -1: "#2ca02c",  # green
    -2: "#c000c0",  # magenta
}
IMPACT_NAMES: dict[int, str] = {
    0: "I = 0 (no impact)",
    1: "I = 1 (tooth-face impact)",
    2: "I = 2 (double-sided impact)",
    -1: "I = -1 (tooth-back impact)",
    -2: "I = -2 (complete disengagement)",
}

# --- axis labels (symbols of the paper, dimensionless) -----------------------------------------
PARAM_LABELS: dict[str, str] = {
    "w": r"dimensionless mesh frequency $\omega$",
    "b": r"dimensionless backlash $b$",
    "xi": r"mesh damping ratio $\xi$",
    "eps": r"stiffness fluctuation $\varepsilon$",
    "Fm": r"mean load $F_m$",
    "Fe": r"error amplitude $F_e$",
}
PARAM_SYMBOLS: dict[str, str] = {"w": r"$\omega$", "b": r"$b$", "xi": r"$\xi$",
                                 "eps": r"$\varepsilon$", "Fm": r"$F_m$", "Fe": r"$F_e$"}
X_LABEL = r"mesh displacement $x$ (= $X_n/b_c$)"
V_LABEL = r"mesh velocity $\dot x$ (= $dx/d\tau$)"
TAU_LABEL = r"dimensionless time $\tau$ (= $\omega_n t$)"
DC_LABEL = "disengagement duty cycle DC"
LOAD_LABEL = r"mesh force over the mean load $F_n/F_m$"  # not Kmax (cell.motion.KMAX_DEFINITION)

DPI = 200


def param_label(name: str) -> str:
    return PARAM_LABELS.get(name, name)


def param_symbol(name: str) -> str:
    return PARAM_SYMBOLS.get(name, name)


def kmax_label(reading: str | None = None) -> str:
    """Axis label of Kmax with its definition, or of another reading under its own name (see
    :data:`gearsim.cell.motion.KMAX_READINGS`)."""
    from gearsim.cell.motion import DEFAULT_KMAX

    reading = reading or DEFAULT_KMAX
    norm = r"F_m + F_e\omega^2" if reading.endswith("static") else "F_m"
    where = "peak" if "_peak_" in reading else "section"
    name = r"$K_{\max}$" if reading == DEFAULT_KMAX else reading.replace("_", r"\_")
    return rf"{name} ({where} $F_n$ / $({norm})$)"


def impact_colour(I: int) -> str:
    return IMPACT_COLOURS.get(int(I), "#7f7f7f")


# --- pattern categories -----------------------------------------------------------------------
# (key, legend label, colour, hatch); keys are produced by :func:`pattern_category`.
# Hatches are kept for legends drawn over patches; the maps themselves use flat colours.
_PATTERNS: list[tuple[str, str, str, str]] = [
    ("0/1T", "0/1T no impact", "#e41a1c", ""),
    ("1/1T", "1/1T face impact", "#ffd92f", ""),
    ("1/2T", "1/2T", "#4daf4a", ""),
    ("1/4T", "1/4T", "#00bcd4", ""),
    ("1/8T", "1/8T", "#984ea3", ""),
    ("1/nT", "1/nT, other n", "#a6761d", ""),
    ("2/1T", "2/1T double-sided", "#08306b", ""),
    ("2/2T", "2/2T double-sided", "#2171b5", ""),
    ("2/4T", "2/4T double-sided", "#6baed6", ""),
    ("2/8T", "2/8T double-sided", "#c6dbef", ""),
    ("2/nT", "2/nT double-sided, other n", "#f781bf", ""),
    ("-1/nT", "-1/nT back impact", "#66c2a5", ""),
    ("0/nT", "0/nT, n > 1", "#fb9a99", ""),
    ("-2/nT", "-2/nT disengaged", "#ff7f00", ""),
    ("chaos2", "chaos, double-sided", "#3a3a3a", ""),
    ("quasi2", "quasi-periodic, double-sided", "#7a7a7a", ""),
    ("chaos1", "chaos, face impact", "#b0b0b0", ""),
    ("quasi1", "quasi-periodic, face impact", "#dcdcdc", ""),
    ("chaos0", "chaos / quasi-periodic, other I", "#969696", ""),
    ("other", "unsettled / diverged", "#ffffff", ""),
]
PATTERN_KEYS = [p[0] for p in _PATTERNS]
PATTERN_LABELS = {p[0]: p[1] for p in _PATTERNS}
PATTERN_COLOURS = {p[0]: p[2] for p in _PATTERNS}
PATTERN_HATCHES = {p[0]: p[3] for p in _PATTERNS}


def pattern_category(motion: str, I: int, n: int) -> str:
    """Map a classified cell to one of :data:`PATTERN_KEYS`."""
    I = int(I)
    n = int(n) if n is not None and not (isinstance(n, float) and np.isnan(n)) else 0
    if motion == "periodic" and n > 0:
        if I == 0:
            return "0/1T" if n == 1 else "0/nT"
        if I == 1:
            return f"1/{n}T" if n in (1, 2, 4, 8) else "1/nT"
        if I == 2:
            return f"2/{n}T" if n in (1, 2, 4, 8) else "2/nT"
        if I == -1:
            return "-1/nT"
        return "-2/nT"
    if motion in ("chaos", "quasi-periodic"):
        kind = "chaos" if motion == "chaos" else "quasi"
        if I == 2:
            return f"{kind}2"
        if I == 1:
            return f"{kind}1"
        return "chaos0"
    return "other"


def pattern_categories(df) -> np.ndarray:
    """Category key of every row of a cells / sweep table."""
    return np.array(
        [
            pattern_category(m, i, n)
            for m, i, n in zip(df["motion"], df["I"], df["n"].fillna(0), strict=True)
        ],
        dtype=object,
    )


# --- DC bands of the I:DC diagrams ---------------------------------------------------------
# The paper's prose lists bands 0.0, 0.0-0.1, 0.1-0.2, ..., 0.7-0.8 (Fig 12b) and merges some
# (0.4-0.6 in Fig 12b, 0.0-0.2 in Fig 16b); we use the common 0.1-wide bands.
DC_EDGES = np.round(np.arange(0.0, 1.0001, 0.1), 10)


def dc_band(dc: float) -> str:
    """Band label of a DC value: ``"0.0"`` for exactly zero, else ``"0.1-0.2"`` style."""
    if not np.isfinite(dc):
        return "n/a"
    if dc <= 1e-12:
        return "0.0"
    k = min(int(np.ceil(dc * 10 - 1e-9)) - 1, 9)
    k = max(k, 0)
    return f"{DC_EDGES[k]:.1f}\u2013{DC_EDGES[k + 1]:.1f}"


def save_figure(fig, out: str | Path) -> list[Path]:
    """Write ``out`` (PNG at :data:`DPI`) and the PDF with the same stem; return both paths."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    png = out.with_suffix(".png")
    pdf = out.with_suffix(".pdf")
    for path, kw in ((png, {"format": "png", "dpi": DPI}), (pdf, {"format": "pdf"})):
        # a temporary name renamed into place: a full disk keeps the previous figure whole
        tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
        try:
            fig.savefig(tmp, bbox_inches="tight", **kw)
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
    return [png, pdf]


def plane_axes(ax, x_name: str, y_name: str) -> None:
    """Label the axes of a parameter plane with the parameters' symbols."""
    ax.set_xlabel(param_label(x_name))
    ax.set_ylabel(param_label(y_name))


def finish(fig, title: str | None, *, rect: tuple[float, float, float, float] | None = None
           ) -> None:
    """The figure's title (when given) and its tight layout (``rect``: the area of the axes)."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=rect)


def note_box(ax, text: str, loc: str = "upper left", fontsize: float = 7.5) -> None:
    """A small boxed note inside an axes (used to flag where our figure differs)."""
    xy = {"upper left": (0.02, 0.98, "left", "top"), "upper right": (0.98, 0.98, "right", "top"),
          "lower left": (0.02, 0.02, "left", "bottom"),
          "lower right": (0.98, 0.02, "right", "bottom")}[loc]
    ax.text(xy[0], xy[1], text, transform=ax.transAxes, ha=xy[2], va=xy[3], fontsize=fontsize,
            bbox={"boxstyle": "round,pad=0.3", "fc": "#fff8dc", "ec": "#b8860b", "alpha": 0.9},
            zorder=10)


def physical_axes(fig, physical: dict, xname: str, yname: str | None = None) -> list[str]:
    """Second axes in physical units on every 2-D panel of ``fig`` whose x (y) axis is the
    parameter ``xname`` (``yname``): on top (right), ``physical[name] = {name, unit, k}`` with
    ``value_phys = k * value`` (:func:`gearsim.physical.units.physical_factors`). Returns the
    labels added."""
    added = []
    for ax in list(fig.axes):
        if ax.name != "rectilinear":
            continue
        for which, name in (("x", xname), ("y", yname)):
            ph = physical.get(name) if name else None
            label = ax.get_xlabel() if which == "x" else ax.get_ylabel()
            if not ph or label != param_label(name):
                continue
            k = float(ph["k"])
            funcs = (lambda v, k=k: v * k, lambda v, k=k: v / k)
            sec = (ax.secondary_xaxis("top", functions=funcs) if which == "x"
                   else ax.secondary_yaxis("right", functions=funcs))
            text = f"{ph['name']} [{ph['unit']}]"
            (sec.set_xlabel if which == "x" else sec.set_ylabel)(text, fontsize=8)
            sec.tick_params(labelsize=7)
            if which == "x" and ax.get_title():  # the panel's title above the new axis
                ax.set_title(ax.get_title(), pad=30, fontsize=ax.title.get_fontsize())
            added.append(text)
    if added and getattr(fig, "_suptitle", None) is not None:
        fig._suptitle.set_y(1.05)
    return sorted(set(added))

