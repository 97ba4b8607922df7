"""Units and meanings of every catalogue column and of the model parameters (one source).

The catalogue stores them as its ``column_dictionary`` table (:mod:`gearsim.results.catalogue`) and
:mod:`gearsim.results.export` writes them as the ``units`` / ``long_name`` attributes of an exported
plane. Every result is dimensionless (docs/model.md, "Coordinates and scalings"): lengths over
the nominal length ``b_c``, time ``tau = w_n t``, forces over ``Km b_c``. A unit is written as
``1`` for a pure number, followed by the scaling in brackets where there is one.
"""

from __future__ import annotations

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION, KMAX_READINGS
from gearsim.cell.record import UNSTEADY_NULL
from gearsim.dynamics.parameters import MODEL_MEANING
from gearsim.dynamics.parameters import PARAMETERS as MODEL_PARAMETERS

#: when the columns of a cell's period are NULL
_NO_PERIOD = "NULL without a period (n = 0: chaos, quasi-periodic, unsettled, diverged)"
#: when a column of a Newton-refined orbit is NULL
_NO_NEWTON = "NULL where Newton did not converge (flag no_convergence)"
#: when a column of a job's provenance is NULL
_NO_PROVENANCE = "NULL where the job's file does not record it (files of older versions)"

#: Model parameters: (unit, meaning), read from where each is defined
#: (:data:`gearsim.dynamics.parameters.PARAMETERS`; the names of its ``ModelParameters``).
PARAMETERS: dict[str, tuple[str, str]] = {
    "model": ("", MODEL_MEANING),
    **{name: (spec.unit, spec.meaning) for name, spec in MODEL_PARAMETERS.items()},
}

#: Columns of a classified cell (``CellResult.row()``; ``I`` is stored as ``impact``).
RESULT: dict[str, tuple[str, str]] = {
    "motion": ("", "periodic | quasi-periodic | chaos | unsettled | diverged"),
    "status": (
        "",
        "ok | bifurcation (a refined orbit within 1e-3 of |mu| = 1) | not_converged | "
        "diverged | budget (how the motion was settled)",
    ),
    "impact": (
        "",
        "impact state I: 0 never disengaged, 1 face impacts only, -1 back impacts only, "
        "2 both, -2 never in contact",
    ),
    "n": ("mesh periods", "period of the motion (0: no period <= n_max)"),
    "p": ("1", f"entries into face contact per motion period; {_NO_PERIOD}"),
    "q": ("1", f"entries into back contact per motion period; {_NO_PERIOD}"),
    "label": ("", "pattern label I/nT, or chaos / quasi-periodic / unsettled / diverged"),
    "label_npq": ("", "n-p-q label ('' without a period)"),
    "dc": ("1", f"fraction of time inside the backlash over the analysed window; {UNSTEADY_NULL}"),
    # Kmax once (gearsim.cell.motion); the other readings under their own names
    "kmax": ("1", f"Kmax, the maximum dynamic load coefficient: {KMAX_DEFINITION} "
                  f"(the same number as {DEFAULT_KMAX}); {UNSTEADY_NULL}"),
    **{k: ("1", f"{v} ({'the reading that is Kmax' if k == DEFAULT_KMAX else 'not Kmax'}); "
                f"{UNSTEADY_NULL}")
       for k, v in KMAX_READINGS.items()},
    "kmin_peak_mean": ("1", f"smallest mesh force over the motion / Fm; {UNSTEADY_NULL}"),
    "lyapunov": ("1/tau", f"largest Lyapunov exponent per unit dimensionless time; "
                          f"{UNSTEADY_NULL}"),
    "x_min": ("1 (X_n / b_c)", "smallest mesh displacement over the analysed window; NULL where "
                               "no period was measured (diverged or out of its step budget "
                               "before its window) or the value left the floating-point range"),
    "x_max": ("1 (X_n / b_c)", "largest mesh displacement over the analysed window; NULL where "
                               "no period was measured (diverged or out of its step budget "
                               "before its window) or the value left the floating-point range"),
    "converged": ("", "true when a period was found (or chaos / quasi-periodic decided)"),
    "window_periods": ("mesh periods", "length of the analysed window"),
    "mu_max": (
        "1 (per motion period)",
        "Floquet margin: largest Floquet multiplier modulus per motion period of the cell's "
        "periodic orbit (< 1 stable; bifurcation curves are where it reaches 1): the Newton-"
        "refined orbit's, else the monodromy of the cell's own RK4 map at its settled state "
        "(integration: floquet: margin); NULL without a period, for variable-ratio and DP5 "
        "cells, and for the unrefined cells of a run with floquet: slow",
    ),
    "critical": ("", "kind of that multiplier: fold | period_doubling | neimark_sacker"),
    "refined": ("", "true when the label is that of the Newton-refined orbit (slow settling)"),
    "settle": (
        "1 (of the x range)",
        "estimated distance of the last section point from the periodic orbit it settles to; "
        + _NO_PERIOD,
    ),
    "mu_lin": (
        "1 (per mesh period)",
        "motions without a period: largest Floquet multiplier modulus of the mesh's linear "
        "limit (the model at b = 0, no clearance; > 1: a nearly linear motion grows without "
        "bound); NULL for the other motions",
    ),
    "long_run": (
        "mesh periods",
        "where mu_lin > 1: periods of the long run from the window's end that showed the motion "
        "bounded (its label stands) or growing (status diverged); NULL where none was needed",
    ),
    "periods": ("mesh periods", "mesh periods integrated in all for this cell"),
    "steps": ("1", "integrator steps taken for this cell"),
}

_ID = ("", "row id")
_JSON_PARAMS = ("JSON", "every model parameter value held fixed (the axes are not listed)")

#: ``(table, column) -> (unit, meaning)`` for every table of the catalogue (tests check that
#: every column created by the schema has an entry).
CATALOGUE: dict[tuple[str, str], tuple[str, str]] = {
    ("catalogue_info", "key"): ("", "name of the build fact"),
    ("catalogue_info", "value"): (
        "JSON",
        "its value: schema_version, built (UTC), git_commit, git_dirty, gearsim_version, "
        "code_versions, integration (when all planes and sweeps agree), counts",
    ),
    ("column_dictionary", "table_name"): ("", "table of the column"),
    ("column_dictionary", "column_name"): ("", "column name"),
    ("column_dictionary", "unit"): ("", "unit ('1' = dimensionless, scaling in brackets)"),
    ("column_dictionary", "meaning"): ("", "what the column holds"),
    ("runs", "id"): _ID,
    ("runs", "kind"): ("", "tile | sweep | audit: the job that produced the data"),
    ("runs", "name"): ("", "plane or sweep name"),
    ("runs", "tile"): ("", "tile number within the plane; NULL for sweeps and audits"),
    ("runs", "file"): ("", f"the Parquet file the data came from; {_NO_PROVENANCE}"),
    ("runs", "config_hash"): ("", "sha256 (16 hex) of the configuration subtree of the job"),
    ("runs", "code_version"): ("", "sha256 (16 hex) of the sources that determine results"),
    ("runs", "package_versions"): ("JSON", "python and package versions of the job"),
    ("runs", "parameters_source"): ("", "standard-parameter file, or builtin-defaults; "
                                    + _NO_PROVENANCE),
    ("runs", "tangent_seed"): ("", "seed of the Lyapunov tangent vector; " + _NO_PROVENANCE),
    ("runs", "audit_seed"): ("", "seed of the audit sample; NULL except for audits"),
    ("runs", "host"): ("", "host name of the job; " + _NO_PROVENANCE),
    ("runs", "workers"): ("", "dask workers (or in-process) of the job; " + _NO_PROVENANCE),
    ("runs", "started"): ("UTC", f"job start; {_NO_PROVENANCE}"),
    ("runs", "finished"): ("UTC", f"job end; {_NO_PROVENANCE}"),
    ("runs", "wall_s"): ("s", "wall time of the job; " + _NO_PROVENANCE),
    ("runs", "cells"): ("1", "cells (or sweep points, audited cells) the job produced; "
                        + _NO_PROVENANCE),
    ("runs", "status"): ("", "ok | budget (stopped at its budget: partial results) | "
                         "skipped (nothing to follow: e.g. a plane of mostly diverged cells); "
                         "never NULL (a catalogue migrated from schema version 2 marks its "
                         "runs ok)"),
    ("planes", "id"): _ID,
    ("planes", "name"): ("", "plane name (config key planes.<name>)"),
    ("planes", "x_name"): ("", "parameter on the x axis (columns cells.x, cells.i)"),
    ("planes", "x_min"): ("as x_name", "lower edge of the x axis"),
    ("planes", "x_max"): ("as x_name", "upper edge of the x axis"),
    ("planes", "x_n"): ("1", "cells along x; centres x_min + (i + 0.5)(x_max - x_min)/x_n"),
    ("planes", "y_name"): ("", "parameter on the y axis (columns cells.y, cells.j)"),
    ("planes", "y_min"): ("as y_name", "lower edge of the y axis"),
    ("planes", "y_max"): ("as y_name", "upper edge of the y axis"),
    ("planes", "y_n"): ("1", "cells along y; centres y_min + (j + 0.5)(y_max - y_min)/y_n"),
    ("planes", "fixed"): ("JSON", "the plane's own overrides (config planes.<name>.fixed)"),
    ("planes", "parameters"): _JSON_PARAMS,
    ("planes", "config_hash"): ("", "hash of the plane's configuration subtree (= its tiles')"),
    ("planes", "code_version"): ("", "code version of the plane's tiles"),
    ("planes", "integration"): ("JSON", "integration settings (IntegrationSettings fields)"),
    ("cells", "id"): _ID,
    ("cells", "plane_id"): ("", "planes.id"),
    ("cells", "run_id"): ("", "runs.id of the tile job"),
    ("cells", "i"): ("1", "x index, 0 .. x_n - 1"),
    ("cells", "j"): ("1", "y index, 0 .. y_n - 1"),
    ("cells", "x"): ("as planes.x_name", "value of the x parameter at the cell centre"),
    ("cells", "y"): ("as planes.y_name", "value of the y parameter at the cell centre"),
    ("cells", "elapsed_s"): ("s", "wall time of the cell; NULL where its tile does not record "
                                  "it"),
    ("sweeps", "id"): _ID,
    ("sweeps", "name"): ("", "sweep name (config key sweeps.<name>)"),
    ("sweeps", "run_id"): ("", "runs.id of the sweep job"),
    ("sweeps", "parameter"): ("", "swept parameter"),
    ("sweeps", "min"): ("as parameter", "first value"),
    ("sweeps", "max"): ("as parameter", "last value"),
    ("sweeps", "n"): ("1", "values, end points included"),
    ("sweeps", "direction"): ("", "forward | backward continuation"),
    ("sweeps", "fixed"): ("JSON", "the sweep's own parameter overrides (sweeps.<name>.fixed)"),
    ("sweeps", "parameters"): ("JSON", "every parameter value held fixed (the swept one omitted)"),
    ("sweeps", "config_hash"): ("", "hash of the sweep's configuration subtree"),
    ("sweeps", "integration"): ("JSON", "integration settings (IntegrationSettings fields)"),
    ("sweep_points", "id"): _ID,
    ("sweep_points", "sweep_id"): ("", "sweeps.id"),
    ("sweep_points", "k"): ("1", "position in the sweep order"),
    ("sweep_points", "value"): ("as sweeps.parameter", "value of the swept parameter"),
    ("sweep_points", "poincare_x"): ("JSON, 1 (X_n / b_c)", "Poincare-section displacements"),
    ("sweep_points", "poincare_v"): ("JSON, 1 (X_n' / b_c)", "Poincare-section velocities"),
    ("audits", "id"): _ID,
    ("audits", "cell_id"): ("", "cells.id of the audited cell"),
    ("audits", "run_id"): ("", "runs.id of the audit job"),
    ("audits", "label"): RESULT["label"],
    ("audits", "label_npq"): RESULT["label_npq"],
    ("audits", "impact"): RESULT["impact"],
    ("audits", "dc"): RESULT["dc"],
    ("audits", "kmax"): RESULT["kmax"],
    ("audits", "lyapunov"): RESULT["lyapunov"],
    ("audits", "agree"): ("", "same label and n-p-q as the catalogue cell"),
    ("sweep_points", "direction"): (
        "", "forward | backward: the sweep order that reached the point (hysteresis); NULL "
            "where the sweep's table has no direction column (older tables: forward)"
    ),
    ("cells", "n_attractors"): (
        "1", "distinct attractors (bounded steady motions) that the cell's seeded starts and "
             "its continuation state reached (docs/multistability.md); starts that diverged or "
             "did not settle are not counted, so 0 means every start diverged or none settled "
             "(its attractors row is the one 'diverged' line); NULL where the cell was not "
             "searched: its plane's multistability is off, or the cell is not on the searched "
             "lattice (multistability: every: k searches every k-th cell per axis)"
    ),
    ("attractors", "id"): _ID,
    ("attractors", "cell_id"): ("", "cells.id of the cell"),
    ("attractors", "run_id"): ("", "runs.id of the attractor-tile job"),
    ("attractors", "attractor"): ("", "index of the attractor in its cell (most starts first)"),
    ("attractors", "motion"): RESULT["motion"],
    ("attractors", "label"): RESULT["label"],
    ("attractors", "label_npq"): RESULT["label_npq"],
    ("attractors", "impact"): RESULT["impact"],
    ("attractors", "n"): RESULT["n"],
    ("attractors", "p"): RESULT["p"],
    ("attractors", "q"): RESULT["q"],
    ("attractors", "dc"): RESULT["dc"],
    ("attractors", "kmax"): RESULT["kmax"],
    ("attractors", "lyapunov"): RESULT["lyapunov"],
    ("attractors", "status"): (RESULT["status"][0], RESULT["status"][1]
                               + "; NULL where the attractor tile does not record it"),
    ("attractors", "mu_max"): RESULT["mu_max"],
    ("attractors", "critical"): (RESULT["critical"][0], RESULT["critical"][1]
                                 + "; NULL without a refined orbit"),
    ("attractors", "basin_fraction"): ("1", "share of the cell's seeded starts that reach it"),
    ("attractors", "n_starts"): ("1", "seeded starts that reach it"),
    ("attractors", "n_early"): ("1", "of those, labelled early (certified ellipsoid or "
                                     "recurrence)"),
    ("attractors", "found_by"): (
        "", "who reached it: subset of forward (continuation state), backward, start"
    ),
}
for _table in ("cells", "sweep_points"):
    for _col, _doc in RESULT.items():
        CATALOGUE[(_table, _col)] = _doc
# periodic orbits (docs/orbits.md)
for _t in ("bifurcation_points", "bifurcation_curves"):
    CATALOGUE.update({
        (_t, "id"): _ID,
        (_t, "run_id"): ("", "runs.id of the continuation job"),
        (_t, "plane"): ("", "plane the point belongs to"),
        (_t, "kind"): ("", "fold | period_doubling | neimark_sacker | grazing"),
        (_t, "period"): ("mesh periods", "period n of the orbit at the point"),
        (_t, "boundary"): ("", "contact boundary that grazes (x=+b, x=-b, ...), else empty"),
        (_t, "name"): ("", "continuation parameter"),
        (_t, "value"): ("as the parameter", "its value at the point (located to 1e-8)"),
        (_t, "name2"): ("", "second parameter"),
        (_t, "value2"): ("as the parameter", "its value at the point"),
        (_t, "x"): ("1 (X_n / b_c)", "section displacement x(tau = 0) of the orbit"),
        (_t, "v"): ("1", "section velocity dx/dtau of the orbit"),
        (_t, "mu_max"): ("1", "largest Floquet multiplier modulus (per n mesh periods)"),
        (_t, "multipliers"): ("JSON", "all Floquet multipliers as [re, im], by modulus"),
        (_t, "stable"): ("", "largest multiplier modulus below 1"),
    })
CATALOGUE[("bifurcation_curves", "curve")] = ("", "curve number (one located point followed)")
# the plane atlas (docs/orbits.md, "The plane atlas: its tables"); NULL in older catalogues
for _t in ("bifurcation_points", "bifurcation_curves"):
    CATALOGUE.update({
        (_t, "source"): ("", "map (seeded from a boundary of the plane's pattern map) | sweep "
                         "(from the standard continuation)"),
        (_t, "seed_i"): ("", "grid index i of the first cell beside the seeding edge (-1: sweep)"),
        (_t, "seed_j"): ("", "grid index j of the first cell beside the seeding edge (-1: sweep)"),
        (_t, "seed_i2"): ("", "grid index i of the second cell beside the seeding edge"),
        (_t, "seed_j2"): ("", "grid index j of the second cell beside the seeding edge"),
        (_t, "label_a"): ("", "label I/nT of the first seeding cell ('' for sweep)"),
        (_t, "label_b"): ("", "label I/nT of the second seeding cell ('' for sweep)"),
    })
CATALOGUE.update({
    ("bifurcation_points", "curve"): ("", "bifurcation_curves.curve it seeded (-1: it landed "
                                      "on a curve already followed; NULL: a continuation's "
                                      "point)"),
    ("bifurcation_curves", "flank"): ("", "face (x=+b) | back (x=-b) | bearing (a bearing "
                                      "clearance) for a grazing, else empty"),
    ("bifurcation_curves", "seq"): ("", "index of the point along its curve (0: its first end)"),
    ("bifurcation_curves", "end_first"): ("", "why the curve ends at its first point: edge | "
                                          "codim2 | closed | lost | budget | max_points"),
    ("bifurcation_curves", "end_last"): ("", "why the curve ends at its last point (as "
                                         "end_first)"),
    ("bifurcation_curves", "end_first_detail"): ("", "end_first in words, with the values"),
    ("bifurcation_curves", "end_last_detail"): ("", "end_last in words, with the values"),
    ("bifurcation_curves", "codim2_first"): ("", "codim2_points.point at the first end (-1: "
                                             "none)"),
    ("bifurcation_curves", "codim2_last"): ("", "codim2_points.point at the last end (-1: "
                                            "none)"),
    ("codim2_points", "id"): _ID,
    ("codim2_points", "run_id"): ("", "runs.id of the curves job"),
    ("codim2_points", "plane"): ("", "plane the point belongs to"),
    ("codim2_points", "point"): ("", "point id within the plane"),
    ("codim2_points", "kind"): ("", "pd_grazing | fold_grazing | cusp | double_grazing | pd_pd "
                                "| grazing_grazing"),
    ("codim2_points", "conditions"): ("", "its two defining conditions, e.g. 'period_doubling; "
                                      "grazing x=-b'"),
    ("codim2_points", "period"): ("mesh periods", "period n of the orbit"),
    ("codim2_points", "boundary"): ("", "grazing boundary involved, else empty"),
    ("codim2_points", "name"): ("", "the plane's x parameter"),
    ("codim2_points", "value"): ("as the parameter", "its value at the point"),
    ("codim2_points", "name2"): ("", "the plane's y parameter"),
    ("codim2_points", "value2"): ("as the parameter", "its value at the point"),
    ("codim2_points", "curves"): ("JSON", "bifurcation_curves.curve ids of the curves it joins"),
    ("codim2_points", "curve_kinds"): ("JSON", "their kinds, in the same order"),
    ("codim2_points", "residual_1"): ("1", "|first test function| at the point"),
    ("codim2_points", "residual_2"): ("1", "|second test function| at the point"),
    ("codim2_points", "residual"): ("1", "the larger of the two (< 1e-8 when converged)"),
    ("codim2_points", "step"): ("as the parameters", "last Newton step, the larger of the two "
                                "parameters' (< 1e-6 when converged)"),
    ("codim2_points", "iterations"): ("", "Newton iterations"),
    ("codim2_points", "converged"): ("", "both conditions met to 1e-8, the point fixed to 1e-6"),
    ("codim2_points", "gap_cells"): ("cells", "distance from the joined curves' last points to "
                                     "the point (largest over the curves)"),
    ("codim2_points", "x"): ("1 (X_n / b_c)", "section displacement x(tau = 0) of the orbit"),
    ("codim2_points", "v"): ("1", "section velocity dx/dtau of the orbit"),
    ("codim2_points", "mu_max"): ("1", "largest Floquet multiplier modulus (per n mesh periods)"),
    ("codim2_points", "multipliers"): ("JSON", "all Floquet multipliers as [re, im], by "
                                       "modulus"),
})
# when the atlas's columns are NULL: a catalogue migrated from version 3 has them all NULL;
# codim2_points' numbers are NULL where its table gives none (NaN)
_MIGRATED_NULL = "NULL in a catalogue migrated from schema version 3 (built before the atlas)"
for _key in [("bifurcation_curves", c) for c in (
        "flank", "seq", "end_first", "end_last", "end_first_detail", "end_last_detail",
        "codim2_first", "codim2_last")] + [(t, c) for t in ("bifurcation_points",
                                                            "bifurcation_curves")
                                           for c in ("source", "seed_i", "seed_j", "seed_i2",
                                                     "seed_j2", "label_a", "label_b")]:
    _unit, _meaning = CATALOGUE[_key]
    if "NULL" not in _meaning:
        CATALOGUE[_key] = (_unit, f"{_meaning}; {_MIGRATED_NULL}")
for _col in ("residual_1", "residual_2", "residual", "step", "iterations", "gap_cells", "x", "v",
             "mu_max", "multipliers"):
    _unit, _meaning = CATALOGUE[("codim2_points", _col)]
    CATALOGUE[("codim2_points", _col)] = (
        _unit, f"{_meaning}; NULL where the point's table gives no value (not computed)")
CATALOGUE.update({
    ("cell_orbits", "id"): _ID,
    ("cell_orbits", "cell_id"): ("", "cells.id of the refined cell"),
    ("cell_orbits", "run_id"): ("", "runs.id of the refine-orbits job"),
    ("cell_orbits", "converged"): ("", "Newton reached residual 1e-10"),
    ("cell_orbits", "residual"): ("1", "max |P^n(y) - y| at the refined orbit; " + _NO_NEWTON),
    ("cell_orbits", "mu_max"): ("1", "largest Floquet multiplier modulus (per n mesh periods); "
                                + _NO_NEWTON),
    ("cell_orbits", "kind"): ("", "kind of that multiplier: fold | period_doubling | "
                              "neimark_sacker"),
    ("cell_orbits", "grazing_margin"): ("1 (X_n / b_c)",
                                        "smallest turning-point distance to a contact boundary; "
                                        + _NO_NEWTON),
    ("cell_orbits", "shift"): ("1", "max |orbit - simulated section point| over (x, x'); "
                               + _NO_NEWTON),
    ("cell_orbits", "minimal_period"): ("mesh periods", "true period of the refined orbit"),
    ("cell_orbits", "flag"): ("", "empty when Newton confirms the simulation, else "
                              "no_convergence | unstable | period"),
    ("cell_orbits", "ms"): ("ms", "wall time of the refinement; NULL where the orbit table does "
                            "not record it"),
})

#: the views of :mod:`gearsim.results.views` (one per plane, one per sweep), as documented in the
#: ``column_dictionary`` row ``(view, '*')``; their columns keep the meanings above
VIEWS = {
    "plane": "view of plane {name}: its cells with the axes as columns {x} and {y} (and their "
             "physical units when the axis was given in them)",
    "sweep": "view of sweep {name}: its points with the swept value as column {parameter}",
}
CATALOGUE[("plane_cells", "*")] = ("", "view: cells joined to planes (plane, x_name, y_name)")


def unit(table: str, column: str) -> str:
    return CATALOGUE[(table, column)][0]


def meaning(table: str, column: str) -> str:
    return CATALOGUE[(table, column)][1]
