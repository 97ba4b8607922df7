"""The figure-data tables (the simulations the figures draw, :mod:`gearsim.study.figure_data`):
which there are, what each reads, where it goes and the settings of its simulations. Light: the
workflow's parse, the figure table and the figure jobs read it without loading the integrators.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gearsim.numerics.settings import IntegrationSettings

#: the Parquet metadata key of what a figure-data table states beside its rows (JSON)
FIGURE_DATA_KEY = b"gearsim.figure_data"

#: at least this many transient periods for the figures' own simulations ...
POINT_TRANSIENT = 300
#: ... and this many when continued
POINT_TRANSIENT_CONTINUATION = 200

#: grid points per axis of the basin pictures (Figs 19, 20) ...
BASIN_N = 200
#: ... and in the short test configurations (transient below 100 periods: tiny.yaml)
BASIN_N_SHORT = 48


@dataclass(frozen=True)
class FigureData:
    """A figure-data table: the sweeps it reads and the config points it needs (names of the
    config's ``sweeps:`` and ``points:``); it is made when all of them are configured."""

    sweeps: tuple[str, ...] = ()
    points: tuple[str, ...] = ()


#: every figure-data table, by name
FIGURE_DATA: dict[str, FigureData] = {
    "fig2": FigureData(sweeps=("b015",)),  # steady motions of I = 0, 1, 2 at b = 0.15
    "fig9_11": FigureData(sweeps=("b015",), points=("fig9_11",)),  # the attractor search
    "fig19": FigureData(points=("fig9_11",)),  # basins at Figs 9-11's point
    "fig20": FigureData(sweeps=("hysteresis",)),  # basins inside the fold's hysteresis band
}


def figure_data_tables(config: Mapping[str, Any]) -> list[str]:
    """The figure-data tables a configuration makes (their sweeps and points configured)."""
    sweeps, points = config.get("sweeps") or {}, config.get("points") or {}
    return [name for name, fd in FIGURE_DATA.items()
            if all(s in sweeps for s in fd.sweeps) and all(p in points for p in fd.points)]


def point_settings(settings: IntegrationSettings) -> IntegrationSettings:
    """Settings of the figures' own point simulations: ``settings`` with a transient of at
    least :data:`POINT_TRANSIENT` periods (:data:`POINT_TRANSIENT_CONTINUATION` when
    continued), so a slowly decaying transient is not drawn as a long-period motion. A few
    points only: cheap."""
    return settings.with_(transient=max(settings.transient, POINT_TRANSIENT),
                          transient_continuation=max(settings.transient_continuation,
                                                     POINT_TRANSIENT_CONTINUATION))


def basin_n(settings: IntegrationSettings) -> int:
    """Grid points per axis of a basin picture for ``settings``."""
    return BASIN_N if settings.transient >= 100 else BASIN_N_SHORT
