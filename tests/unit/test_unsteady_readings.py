"""A motion that never settled (diverged, unsettled) has no Kmax, DC or Lyapunov exponent in its
table row (NaN, stored as NULL), while its status says why; every nullable catalogue column's
dictionary row says when it is NULL."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gearsim.cell.record import STEADY_READINGS, UNSTEADY_MOTIONS, Classification, row_values
from gearsim.cell.simulate import CellResult, diverged_result
from gearsim.dynamics.parameters import ModelParameters
from gearsim.results import schema
from gearsim.results.columns import CATALOGUE

#: a periodic reading as the classifier gives it (every reading finite)
PERIODIC = Classification(
    motion="periodic", status="ok", I=1, n=1, p=1, q=0, label="1/1T", label_npq="1-1-0",
    dc=0.25, kmax_peak_mean=3.1, kmax_peak_static=1.4018, kmax_section_mean=2.9,
    kmax_section_static=1.3, kmin_peak_mean=-0.2, lyapunov=-0.05, x_min=-0.4, x_max=1.9,
    converged=True, window_periods=64,
)  # fmt: skip


def _row(cls: Classification) -> dict:
    res = CellResult(cls, np.zeros(10), 0, np.zeros((0, 10)), 100, 1000, ModelParameters())
    return res.row()


@pytest.mark.parametrize("motion,status", [("periodic", "ok"), ("periodic", "not_converged"),
                                           ("chaos", "ok"), ("quasi-periodic", "ok")])
def test_settled_motions_keep_their_readings(motion, status):
    row = _row(replace(PERIODIC, motion=motion, status=status))
    assert row["kmax"] == 1.4018 == row["kmax_peak_static"]
    assert all(math.isfinite(row[k]) for k in STEADY_READINGS)


@pytest.mark.parametrize("motion,status", [("diverged", "diverged"),
                                           ("unsettled", "not_converged"),
                                           ("unsettled", "budget")])
def test_unsteady_motions_have_no_readings(motion, status):
    """What the window read of a diverged or unsettled motion (here a runaway Kmax of ~1e6, as
    the long run of a growing motion leaves it) is not in the row; the status says why and the
    extent of the motion stays."""
    cls = replace(PERIODIC, motion=motion, status=status, label=motion, label_npq="",
                  kmax_peak_static=1_048_804.0, x_max=5.0e3)
    row = _row(cls)
    assert motion in UNSTEADY_MOTIONS
    assert all(math.isnan(row[k]) for k in STEADY_READINGS), row
    assert (row["status"], row["x_max"]) == (status, 5.0e3)
    assert cls.kmax_peak_static == 1_048_804.0  # the classification itself is left alone
    # the cell a tile job writes when the state leaves the divergence bound
    d = diverged_result(ModelParameters(), 10, 100).row()
    assert d["motion"] == "diverged" and all(math.isnan(d[k]) for k in STEADY_READINGS)


def test_row_values_is_the_row():
    assert {k: v for k, v in _row(PERIODIC).items() if k not in ("periods", "steps")} == \
        row_values(PERIODIC)


def test_every_nullable_column_says_when_it_is_null():
    """Each nullable column of every catalogue table has a dictionary row, and the row says
    when the column is NULL; the steady readings say it for unsteady motions."""
    silent = []
    for table in schema.Base.metadata.sorted_tables:
        for col in table.columns:
            if col.nullable and not col.primary_key:
                meaning = CATALOGUE[(table.name, col.name)][1]
                if "NULL" not in meaning:
                    silent.append((table.name, col.name))
    assert not silent, silent
    for col in STEADY_READINGS:
        assert "NULL when the motion is diverged or unsettled" in CATALOGUE[("cells", col)][1]
    n_att = CATALOGUE[("cells", "n_attractors")][1]
    assert "0 means every start diverged" in n_att and "not searched" in n_att
