"""The search: free parameters, the vector-to-parameters map, one bisection, one seeded
differential-evolution driver with its refinement, and the logged objective wrapper.

Every calibration search (the landmark fit, :mod:`gearsim.calibration.calibrate`, and
the per-form fits, :mod:`gearsim.calibration.form_search`) uses these; only the objective differs.
"""

from __future__ import annotations

import gzip
import json
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.dynamics.parameters import ModelParameters

Bounds = Sequence[tuple[float, float]]


@dataclass(frozen=True)
class FreeParameter:
    """One search coordinate: a :class:`ModelParameters` name or a derived coordinate of
    :func:`params_from_vector`, its bounds, its start value (None: none given), its unit and
    meaning."""

    name: str
    lower: float
    upper: float
    start: float | None = None
    unit: str = ""
    text: str = ""


def params_from_vector(x: Sequence[float], free: Sequence[FreeParameter],
                       base: ModelParameters, *, Fm: float, b: float,
                       **fixed: Any) -> ModelParameters:
    """``base`` with ``fixed``, the search scale ``Fm``, ``b`` and the coordinates ``x`` of
    ``free`` (later entries win).

    Derived coordinates: ``Fe_over_Fm`` (``Fe = Fe_over_Fm * Fm``), ``phi_e_deg`` (degrees),
    ``kappa`` (one bearing stiffness for all four directions), ``kappa_ratio`` (bearing stiffness
    over mesh stiffness: ``kappa_ij = ratio * rho_i`` with ``base``'s mass ratios), ``rho`` (one
    mass ratio for both gears), ``b_brg`` (one bearing half clearance for all four directions);
    any other name is a :class:`ModelParameters` field.
    """
    kw: dict[str, Any] = dict(fixed)
    kw.update(Fm=Fm, b=b)
    for fp, v in zip(free, x, strict=True):
        v = float(v)
        if fp.name == "Fe_over_Fm":
            kw["Fe"] = v * Fm
        elif fp.name == "phi_e_deg":
            kw["phi_e"] = math.radians(v)
        elif fp.name == "kappa":
            kw.update(kappa_py=v, kappa_pz=v, kappa_gy=v, kappa_gz=v)
        elif fp.name == "kappa_ratio":
            kw.update(kappa_py=v * base.rho_p, kappa_pz=v * base.rho_p,
                      kappa_gy=v * base.rho_g, kappa_gz=v * base.rho_g)
        elif fp.name == "rho":
            kw.update(rho_p=v, rho_g=v)
        elif fp.name == "b_brg":
            kw.update(b_py=v, b_pz=v, b_gy=v, b_gz=v)
        else:
            kw[fp.name] = v
    return base.with_(**kw)


def bisect_bool(pred: Callable[[float], bool], lo: float, hi: float,
                tol: float | None = None, *, steps: int | None = None) -> float:
    """Midpoint of the final bracket of ``[lo, hi]`` where ``pred`` turns from true (at ``lo``)
    to false (at ``hi``): bisected to width ``tol`` (> 0), or exactly ``steps`` times."""
    if (steps is None) == (tol is None) or (tol is not None and not tol > 0):
        raise ValueError("bisect_bool: give either tol > 0 or steps")
    n = 0
    while (hi - lo > tol) if steps is None else (n < steps):
        mid = 0.5 * (lo + hi)
        if pred(mid):
            lo = mid
        else:
            hi = mid
        n += 1
    return 0.5 * (lo + hi)


class LoggedObjective:
    """Picklable objective for the search (``workers=`` map): ``point(x) -> (J, record)``; every
    call is appended as one JSON line to ``log_pattern.format(pid=...)``; a failed evaluation
    is a bad point (``J = bad``, the error recorded), not a crash."""

    def __init__(self, point: Callable[[np.ndarray], tuple[float, dict[str, Any]]],
                 log_pattern: str | None = None, bad: float = 1e3):
        self.point = point
        self.log_pattern = log_pattern
        self.bad = bad

    def evaluate(self, x: np.ndarray) -> tuple[float, dict[str, Any]]:
        xs = [float(v) for v in x]
        try:
            J, rec = self.point(x)
            rec = {"x": xs, **rec}
        except Exception as exc:  # noqa: BLE001 - a failed evaluation is a bad point
            J = self.bad
            rec = {"x": xs, "J": J, "error": repr(exc)}
        if self.log_pattern:
            with open(self.log_pattern.format(pid=os.getpid()), "a") as fh:
                fh.write(json.dumps(rec, default=float) + "\n")
        return float(J), rec

    def __call__(self, x: np.ndarray) -> float:
        return self.evaluate(x)[0]


def log_files(log_dir: str | Path, pattern: str = "*") -> list[Path]:
    """The evaluation logs ``<pattern>.jsonl`` in ``log_dir``, and ``<pattern>.jsonl.gz``: the
    log of a finished lane fit is kept compressed (:func:`compress_log`)."""
    d = Path(log_dir)
    return sorted([*d.glob(f"{pattern}.jsonl"), *d.glob(f"{pattern}.jsonl.gz")])


def log_lines(path: str | Path) -> list[str]:
    """The lines of an evaluation log, plain or gzip-compressed (by its name)."""
    p = Path(path)
    if p.suffix == ".gz":
        with gzip.open(p, "rt") as fh:
            return fh.read().splitlines()
    return p.read_text().splitlines()


def compress_log(path: str | Path) -> Path:
    """``<path>.gz`` in place of the plain log ``path`` (a finished fit's log is read, never
    appended to); returns the compressed file."""
    p = Path(path)
    gz = p.with_name(p.name + ".gz")
    with p.open("rb") as src, gzip.open(gz, "wb", compresslevel=9) as dst:
        dst.write(src.read())
    p.unlink()
    return gz


def logged_evaluations(log_dir: str | Path) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """Every logged evaluation with a measurement in ``<log_dir>/<form>-<level>.<tag>.jsonl``
    (or its compressed ``.jsonl.gz``; the logs of :class:`LoggedObjective` and of the lane
    fits), as ``(form, level, record)`` in file and line order."""
    for f in log_files(log_dir):
        form, level = f.name.split(".")[0].rsplit("-", 1)
        for line in log_lines(f):
            rec = json.loads(line)
            if rec.get("measured"):
                yield form, level, rec


def sobol_population(bounds: Bounds, size: int, seed: int,
                     x0: Sequence[float] | None = None) -> np.ndarray:
    """Scrambled-Sobol initial population in ``bounds`` (seeded); row 0 is ``x0`` if given."""
    from scipy.stats import qmc

    d = len(bounds)
    u = qmc.Sobol(d, scramble=True, seed=seed).random(size)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    pop = lo + u * (hi - lo)
    if x0 is not None:
        pop[0] = np.clip(np.asarray(x0, dtype=float), lo, hi)
    return pop


def run_de(fun: Callable[[np.ndarray], float], bounds: Bounds, *, seed: int, generations: int,
           population: int = 16, x0: Sequence[float] | None = None, workers: int = 1,
           tol: float = 0.0, time_budget: float | None = None) -> dict[str, Any]:
    """Seeded differential evolution (scipy; Sobol initial population of ``population``, member
    0 = ``x0``; ``updating='deferred'``, no polish). Reproducible: the same seed, bounds,
    population and generations give the same result (``workers`` only changes where the
    evaluations run). ``tol`` is scipy's relative convergence stop (0: run every generation);
    ``time_budget`` (seconds) stops after the generation that exceeds it (recorded)."""
    from scipy.optimize import differential_evolution

    t0 = time.time()
    c0 = time.process_time()
    history: list[dict[str, Any]] = []
    stopped = {"time": False}

    def cb(intermediate_result):
        history.append({"t": time.time() - t0, "J": float(intermediate_result.fun),
                        "x": [float(v) for v in intermediate_result.x]})
        if time_budget is not None and time.time() - t0 > time_budget:
            stopped["time"] = True
            return True
        return False

    init = sobol_population(bounds, population, seed, x0)
    res = differential_evolution(fun, bounds, init=init, seed=seed, maxiter=generations,
                                 tol=tol, atol=0.0, polish=False, updating="deferred",
                                 workers=workers, callback=cb)
    return {"x": [float(v) for v in res.x], "J": float(res.fun), "nfev": int(res.nfev),
            "nit": int(res.nit), "message": str(res.message), "seed": seed,
            "population": population, "generations": generations, "workers": workers,
            "stopped_by_time": stopped["time"], "wall_s": time.time() - t0,
            "cpu_s_main": time.process_time() - c0, "history": history,
            "population_final": [[float(v) for v in r] for r in res.population],
            "population_energies": [float(v) for v in res.population_energies]}


def refine(fun: Callable[[np.ndarray], float], x0: Sequence[float], bounds: Bounds, *,
           maxfev: int, step: float = 0.05) -> dict[str, Any]:
    """Bounded Nelder-Mead from ``x0`` (initial simplex ``step`` of each box width)."""
    from scipy.optimize import minimize

    x0 = np.asarray(x0, dtype=float)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    d = len(x0)
    simplex = np.repeat(x0[None, :], d + 1, axis=0)
    for k in range(d):
        h = step * (hi[k] - lo[k])
        simplex[k + 1, k] = x0[k] + h if x0[k] + h <= hi[k] else x0[k] - h
    res = minimize(fun, x0, method="Nelder-Mead", bounds=list(zip(lo, hi, strict=True)),
                   options={"maxfev": maxfev, "initial_simplex": simplex, "xatol": 1e-6,
                            "fatol": 1e-6})
    return {"x": [float(v) for v in res.x], "J": float(res.fun), "nfev": int(res.nfev)}


def search(fun: Callable[[np.ndarray], float], bounds: Bounds, *, seed: int,
           generations: int, population: int = 16, x0: Sequence[float] | None = None,
           workers: int = 1, tol: float = 0.0, time_budget: float | None = None,
           refine_fun: Callable[[np.ndarray], float] | None = None, refine_top: int = 4,
           refine_fev: int = 16) -> dict[str, Any]:
    """Differential evolution (:func:`run_de`) on ``fun``, then, with ``refine_fun`` (a finer
    objective), the refinement: the best ``refine_top`` distinct members of the final population
    scored by ``refine_fun`` and Nelder-Mead (:func:`refine`, ``refine_fev`` evaluations) from
    the best of them.

    Returns ``{"de": ..., "x": best vector, "J": its value}`` and, with refinement,
    ``"candidates"`` (``[(J, x)]``), ``"refine"`` and ``"nfev_refine"``.
    """
    de = run_de(fun, bounds, seed=seed, generations=generations, population=population,
                x0=x0, workers=workers, tol=tol, time_budget=time_budget)
    out: dict[str, Any] = {"de": de, "x": np.asarray(de["x"]), "J": de["J"]}
    if refine_fun is None:
        return out
    pop = np.asarray(de["population_final"])
    order = np.argsort(np.asarray(de["population_energies"]))
    cand: list[np.ndarray] = []
    for i in order:
        if not any(np.allclose(pop[i], c) for c in cand):
            cand.append(pop[i])
        if len(cand) >= refine_top:
            break
    scored = [(refine_fun(c), c) for c in cand]
    Jbest, xbest = min(scored, key=lambda t: t[0])
    nm = refine(refine_fun, xbest, bounds, maxfev=refine_fev)
    if nm["J"] < Jbest:
        xbest, Jbest = np.asarray(nm["x"]), nm["J"]
    out.update(x=np.asarray(xbest), J=Jbest, candidates=scored, refine=nm,
               nfev_refine=len(scored) + nm["nfev"])
    return out


def run_cmaes(batch: Callable[[list[np.ndarray]], list[float]], bounds: Bounds, *, seed: int,
              x0: Sequence[float] | None = None, sigma0: float = 0.25,
              popsize: int | None = None, max_evals: int = 3000, min_evals: int = 0,
              flat_evals: int = 600, flat_rtol: float = 0.01, restarts: int = 9,
              time_budget: float | None = None,
              on_generation: Callable[[dict[str, Any]], None] | None = None,
              checkpoint: str | Path | None = None) -> dict[str, Any]:
    """CMA-ES (the ``cma`` package) with IPOP restarts on ``batch`` (a population's vectors ->
    their J, e.g. one batched-kernel measurement), in the unit cube mapped onto ``bounds``.

    The first run starts at ``x0`` (else the box centre; ``x0`` itself is evaluated in the first
    batch), each restart at a seeded uniform point with twice the population. A run ends on
    cma's criteria or when its best J fell by less than ``flat_rtol`` (relative) over its last
    ``flat_evals`` evaluations. The search ends flat when a whole restart did not lower the best
    J of the runs before it by ``flat_rtol`` (after ``min_evals`` at least), at ``max_evals``,
    after ``restarts`` restarts, or past ``time_budget`` seconds of this call (``stopped_by``).

    With ``checkpoint`` (a file) the whole search (cma's state, the seeded generator, curve,
    runs) is written there after every generation and resumed from it: an interrupted search
    continues exactly as if it had not stopped, a budget-stopped one continues with a larger
    budget; another search's checkpoint (bounds, start, seed, sigma0 or population differ) is
    refused with :class:`gearsim.errors.UsageError` naming the file.

    ``on_generation`` gets after every generation ``nfev``, ``best_J``, ``x``, the run's index,
    wall and CPU seconds over all calls (``t``, ``cpu_s``), the curve and the finished runs.
    Returns the best vector and J, ``nfev``, the best-J curve (``[nfev, best J]`` per
    generation), the runs (population, evaluations, best J, why each ended), ``resumed``, wall
    and CPU seconds over all calls.
    """
    import cma

    lo = np.array([b[0] for b in bounds], dtype=float)
    hi = np.array([b[1] for b in bounds], dtype=float)
    d = len(lo)
    t0 = time.time()
    c0 = time.process_time()
    key = {"bounds": [[float(a), float(b)] for a, b in zip(lo, hi, strict=True)],
           "x0": None if x0 is None else [float(v) for v in x0], "seed": int(seed),
           "sigma0": float(sigma0), "popsize": popsize}
    S = _load_checkpoint(checkpoint, key)
    if S is None:
        S = _fresh_search(key, lo, hi, popsize)
    else:
        S["resumed"] += 1
        S["why"] = "" if S["why"] in ("max_evals", "time_budget") else S["why"]
    best, curve, runs = S["best"], S["curve"], S["runs"]
    stopped_by = ""

    def clock() -> tuple[float, float]:
        return S["wall_s"] + time.time() - t0, S["cpu_s"] + time.process_time() - c0

    while S["r"] <= restarts:
        if S["es"] is None:
            S["es"] = cma.CMAEvolutionStrategy(
                np.clip(S["u0"], 0.0, 1.0).tolist(), sigma0,
                {"bounds": [0.0, 1.0], "popsize": S["lam"],
                 "seed": int(S["rng"].integers(1, 2**31 - 1)),
                 "verbose": -9, "verb_log": 0, "verb_disp": 0})
            S["run"] = {"popsize": S["lam"], "start_nfev": S["nfev"], "best_J": math.inf}
            S["rcurve"] = []
        es, run = S["es"], S["run"]
        while not S["why"]:
            _generation(S, batch, lo, hi)
            if S["nfev"] >= max_evals:
                S["why"] = "max_evals"
            elif time_budget is not None and time.time() - t0 > time_budget:
                S["why"] = "time_budget"
            elif es.stop():
                S["why"] = "cma: " + ",".join(sorted(es.stop()))
            elif _flat(S["rcurve"], run["start_nfev"], flat_evals, flat_rtol):
                S["why"] = "run flat"
            wall, cpu = clock()
            _save_checkpoint(checkpoint, S, wall, cpu)
            if on_generation:
                on_generation({"nfev": S["nfev"], "best_J": best["J"], "x": best["x"],
                               "run": S["r"], "t": wall, "cpu_s": cpu, "curve": curve,
                               "runs": runs})
        why = S["why"]
        if why in ("max_evals", "time_budget"):
            stopped_by = why
        run.update(nfev=S["nfev"] - run["start_nfev"], stopped_by=why)
        before = min((q["best_J"] for q in runs), default=math.inf)
        runs.append(run)
        if not stopped_by and S["nfev"] >= min_evals and math.isfinite(before) and not (
                before - run["best_J"] > flat_rtol * abs(before)):
            stopped_by = "flat"
        if stopped_by:
            # the run is kept open in the checkpoint: a larger budget continues it
            runs.pop()
            break
        S["lam"] *= 2
        S["u0"] = S["rng"].random(d)
        S["es"], S["why"] = None, ""
        S["r"] += 1
        wall, cpu = clock()
        _save_checkpoint(checkpoint, S, wall, cpu)
    else:
        stopped_by = "restarts"
    wall, cpu = clock()
    out_runs = runs + ([run] if stopped_by in ("max_evals", "time_budget", "flat") else [])
    return {"x": best["x"], "J": best["J"], "nfev": S["nfev"], "curve": curve,
            "runs": out_runs, "stopped_by": stopped_by, "seed": seed, "wall_s": wall,
            "cpu_s": cpu, "resumed": S["resumed"]}


def _fresh_search(key: dict[str, Any], lo: np.ndarray, hi: np.ndarray, popsize: int | None
                  ) -> dict[str, Any]:
    """The state of a search not begun: its first run at the start (else the box centre)."""
    x0, d = key["x0"], len(lo)
    u0 = np.full(d, 0.5) if x0 is None else (np.asarray(x0, dtype=float) - lo) / (hi - lo)
    return {"key": key, "rng": np.random.default_rng(key["seed"]), "r": 0,
            "lam": popsize or (4 + int(3 * math.log(d))), "u0": u0,
            "start": [] if x0 is None else [np.clip(np.asarray(x0, dtype=float), lo, hi)],
            "best": {"J": math.inf, "x": None}, "curve": [], "runs": [], "nfev": 0,
            "es": None, "run": None, "rcurve": [], "why": "", "wall_s": 0.0, "cpu_s": 0.0,
            "resumed": 0}


def _generation(S: dict[str, Any], batch: Callable[[list[np.ndarray]], list[float]],
                lo: np.ndarray, hi: np.ndarray) -> None:
    """One generation of the search ``S``: ask cma, measure the batch, tell cma, update the
    evaluations, the best set and both curves."""
    es, run, best = S["es"], S["run"], S["best"]
    us = es.ask()
    xs = [lo + np.asarray(u) * (hi - lo) for u in us]
    # the start, exactly, in the first batch (one lane more; not told to cma): cma's bound
    # transform moves a value on a bound inside (0 -> 0.0125 of the box), so the population
    # never holds a start with a coordinate on its bound (b_brg = 0)
    extra, S["start"] = S["start"], []
    Jall = [float(v) for v in batch(extra + xs)]
    es.tell(us, Jall[len(extra):])
    S["nfev"] += len(extra) + len(xs)
    k = int(np.argmin(Jall))
    run["best_J"] = min(run["best_J"], Jall[k])
    if Jall[k] < best["J"]:
        best.update(J=Jall[k], x=[float(v) for v in (extra + xs)[k]])
    S["curve"].append([S["nfev"], best["J"]])
    S["rcurve"].append([S["nfev"], run["best_J"]])


def _flat(c: list[list[float]], since: int, flat_evals: int, flat_rtol: float) -> bool:
    """Best J of curve ``c`` (from evaluation ``since``) fell by less than ``flat_rtol``
    (relative) over its last ``flat_evals`` evaluations."""
    c = [p for p in c if p[0] >= since]
    if not c or c[-1][0] - c[0][0] < flat_evals:
        return False
    past = [J for n, J in c if n <= c[-1][0] - flat_evals]
    if not past:
        return False
    then = past[-1]
    return not (then - c[-1][1] > flat_rtol * abs(then))


def _load_checkpoint(path: str | Path | None, key: dict[str, Any] | None
                     ) -> dict[str, Any] | None:
    """A search written by :func:`_save_checkpoint` at ``path`` with this ``key`` (None: any);
    None when there is none; :class:`UsageError` for another search's."""
    import pickle

    from gearsim.errors import UsageError

    if path is None or not Path(path).is_file():
        return None
    try:
        S = pickle.loads(Path(path).read_bytes())
    except Exception as e:  # noqa: BLE001 - a truncated or foreign file
        raise UsageError(f"{path}: not a search checkpoint ({type(e).__name__}); delete it to "
                         "start the search afresh") from None
    if not isinstance(S, dict) or "key" not in S or (key is not None and S["key"] != key):
        raise UsageError(f"{path}: the checkpoint of another search (bounds, start, seed, sigma0 "
                         "or population differ); delete it to start afresh")
    return S


def checkpoint_evaluations(path: str | Path) -> int | None:
    """How many evaluations the search checkpointed at ``path`` has made (None: no
    checkpoint there; :class:`UsageError` for a file that is not one)."""
    if not Path(path).is_file():
        return None
    S = _load_checkpoint(path, None)
    return int(S["nfev"])


def _save_checkpoint(path: str | Path | None, S: dict[str, Any], wall: float, cpu: float
                     ) -> None:
    """The whole search ``S`` at ``path`` (atomically), its wall and CPU seconds so far."""
    import pickle

    if path is None:
        return
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_bytes(pickle.dumps({**S, "wall_s": wall, "cpu_s": cpu}))
    tmp.replace(p)
