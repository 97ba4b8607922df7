"""The plane atlas against a closed form: the single-DOF model without mesh-stiffness variation
(eps = 0) or friction is linear while the teeth stay in contact, so its face-flank grazing
curve in (w, xi) is where the linear response's amplitude equals the mean load,

    Fm = Fe w^2 / sqrt((1 - w^2)^2 + (2 xi w)^2).

The map the curve is seeded from is labelled by that closed form (0/1T without contact loss,
1/1T with it) and carries the linear steady state as each cell's section state: the seeding,
the location and the following are the atlas's own (`gearsim bifurcation-curves`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.optimize import brentq

from gearsim.cli.main import main
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config_io import load_standard_parameters

STANDARD = ModelParameters.from_mapping(load_standard_parameters("config/standard_parameters.yaml"))
LINEAR = STANDARD.with_(model="1dof", eps=0.0, friction=0.0)
PLANE = {"x": {"name": "w", "min": 0.55, "max": 0.67, "n": 12},
         "y": {"name": "xi", "min": 0.04, "max": 0.16, "n": 8}, "fixed": {}}


def amplitude(p: ModelParameters, w: float, xi: float) -> complex:
    """Complex amplitude of the linear steady response ``x - b - Fm`` (phase at tau = 0)."""
    return p.Fe * w**2 / (1.0 - w**2 + 2j * xi * w) * np.exp(1j * p.phi_e)


def grazing_w(p: ModelParameters, xi: float) -> float:
    """The closed-form face grazing frequency at damping ``xi`` (the lower resonance flank)."""
    return brentq(lambda w: abs(amplitude(p, w, xi)) - p.Fm, 0.4, 0.99, xtol=1e-15)


def linear_cells(p: ModelParameters, plane: dict) -> pd.DataFrame:
    """A map labelled by the closed form, each cell's section state the linear steady state."""
    xs, ys = plane["x"], plane["y"]
    rows = []
    for i in range(xs["n"]):
        w = xs["min"] + (i + 0.5) * (xs["max"] - xs["min"]) / xs["n"]
        for j in range(ys["n"]):
            xi = ys["min"] + (j + 0.5) * (ys["max"] - ys["min"]) / ys["n"]
            X = amplitude(p, w, xi)
            state = np.zeros(10)
            state[0], state[1] = p.b + p.Fm + X.real, (1j * w * X).real
            contact_lost = abs(X) > p.Fm
            rows.append({"i": i, "j": j, "x": w, "y": xi, "w": w, "xi": xi,
                         "motion": "periodic", "status": "ok", "n": 1, "I": int(contact_lost),
                         "p": int(contact_lost), "q": 0,
                         "label": "1/1T" if contact_lost else "0/1T",
                         "final_state": state.tolist()})
    return pd.DataFrame(rows)


def test_face_grazing_curve_is_the_closed_form(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({
        "parameters": {"model": "1dof", "eps": 0.0, "friction": 0.0},
        "planes": {"wxi": PLANE}, "tile_rows": 4,
    }))
    cells = tmp_path / "cells.parquet"
    linear_cells(LINEAR, PLANE).to_parquet(cells)
    out = tmp_path / "orbits" / "wxi_curves.parquet"
    assert main(["bifurcation-curves", "--plane", "wxi", "--configfile", "config/config.yaml",
                 str(cfg), "--cells", str(cells), "--out", str(out)]) == 0
    cur = pd.read_parquet(out)
    graze = cur[(cur["kind"] == "grazing") & (cur["boundary"] == "x=+b")]
    assert graze["curve"].nunique() == 1 and set(graze["period"]) == {1}
    assert set(graze["flank"]) == {"face"} and set(graze["source"]) == {"map"}
    # from one edge of the plane to the other, drawn as finely as the map
    assert graze["value2"].min() == pytest.approx(0.04, abs=1e-12)
    assert graze["value2"].max() == pytest.approx(0.16, abs=1e-12)
    assert set(graze[["end_first", "end_last"]].to_numpy().ravel()) == {"edge"}
    assert np.all(np.diff(graze["value2"].to_numpy()) > 0)
    assert np.max(np.diff(graze["value2"].to_numpy())) <= 40 * 0.12 / 8
    # every point on the closed-form curve to 1e-6 (in w at its xi)
    err = [abs(r.value - grazing_w(LINEAR, r.value2)) for r in graze.itertuples()]
    assert max(err) < 1e-6, max(err)
    # the tables the catalogue and the figures read
    seeds = pd.read_parquet(tmp_path / "orbits" / "wxi_curves_points.parquet")
    assert (seeds["curve"] >= 0).sum() == 1 and set(seeds["label_a"]) <= {"0/1T", "1/1T"}
    codim2 = pd.read_parquet(tmp_path / "orbits" / "wxi_codim2.parquet")
    assert "conditions" in codim2.columns
    assert (tmp_path / "orbits" / "wxi_curves.png").is_file()


def test_pd_grazing_point_where_the_doubling_orbit_first_touches_the_back_flank():
    """A codimension-2 point with a known answer. An orbit that never reaches x = -b sees the
    dead zone only through x - b: shifting x by b removes b from its equations, so the 1T
    orbit's period doubling keeps its w (w*) as b falls, the orbit shifted by the change of b,
    until its lowest turning point x_min(b) = x_min(1) - 1 + b meets -b, at
    b* = (1 - x_min(1)) / 2. The period-doubling curve followed down from b = 1 is lost there;
    the point is located from its end by the Newton solve of the two conditions."""
    from gearsim.analysis.atlas import AtlasOptions
    from gearsim.analysis.atlas_seeds import Grid
    from gearsim.analysis.bifcurves import follow_curve
    from gearsim.analysis.codim2 import codim2_points
    from gearsim.analysis.continuation import continue_orbit
    from gearsim.analysis.continuation_options import Continuation
    from gearsim.analysis.exact_landmarks import bifurcation_points
    from gearsim.analysis.orbits import grazing_margin
    from gearsim.analysis.relocation import section_state

    one = STANDARD.with_(model="1dof")
    br = continue_orbit(one, "w", 0.95, 1.1, n=1, config=Continuation(ds=0.02, switch_depth=0))
    pd_pt = bifurcation_points(br).query("kind == 'period_doubling'").iloc[0]
    x_min = grazing_margin(one.with_(w=pd_pt.value), section_state(pd_pt), 1).x_min
    w_star, b_star = float(pd_pt.value), (1.0 - x_min) / 2.0
    grid = Grid("w", "b", 0.1, 2.5, 400, 0.0, 1.0, 400)
    c = follow_curve(one, pd_pt, "b", 0.0, step2=0.1, range2=(0.0, 1.0), range1=(0.1, 2.5),
                     cell=(grid.dx, grid.dy), max_points=100)
    assert c.attrs["end"] == "lost" and c["value2"].min() > b_star
    end = {"curve": 0, "side": "last", "w": float(c["value"].iloc[-1]),
           "y": float(c["value2"].iloc[-1]), "state": c.attrs["last_state"],
           "tangent": c.attrs["last_tangent"], "end": "lost", "kind": "period_doubling",
           "boundary": "", "period": 1}
    pts = codim2_points(one, c.assign(curve=0), grid, AtlasOptions(), [end])
    assert len(pts) == 1
    p = pts.iloc[0]
    assert p["kind"] == "pd_grazing" and p["boundary"] == "x=-b" and p["converged"]
    assert abs(p["value"] - w_star) < 1e-6 and abs(p["value2"] - b_star) < 1e-6
    assert p["residual"] < 1e-8 and p["step"] < 1e-6
    assert end["codim2"] == 0 and p["gap_cells"] < 0.5  # the curve's end converged to it
    mu = np.array(p["mu_re"]) + 1j * np.array(p["mu_im"])
    assert np.min(np.abs(mu + 1.0)) < 1e-8
