"""The recurrence mapper: model-agnostic, all starts of all cells advancing together chunk by
chunk (the reference the lane-pool mapper is checked against; any model as a :class:`System`).

The method (after the recurrence-based attractor mapping of Datseris, Rossi and Wagemakers,
Chaos 2023) is model-agnostic; a *system* supplies three operations on states of its cells:

``advance(cells, states, n_periods, start_periods)``
    Integrate each state ``n_periods`` forcing periods; return the section states of every period
    (``(k, n, d)``, NaN after a divergence), the final states and a divergence flag per state.
``steady(cells, states, transient, start_periods)``
    The *full-length run* of each state: ``transient`` periods, then measurement and
    classification. Returns one :class:`Steady` per state.
``start_states(cell, unit)``
    Map points of the unit square to full start states (the box of ``(x, x')`` the starts fill).

:func:`map_attractors` then works on section points projected to ``(x, x')`` (the first two
section components) in the system's own units. The gear model is one client
(:class:`gearsim.analysis.attractors.gear.GearCells`); tests/integration/test_attractors.py
drives a hardening Duffing oscillator integrated with scipy through the same code.

Algorithm per cell (all cells and starts of a call advance together as SIMD lanes):

1. *Scouts* - the continuation states (``forward`` / ``backward``, where given) and the first
   ``scouts`` random starts - get the full-length run; their steady motions seed the attractor
   list (merged as below).
2. The other starts advance ``chunk`` periods at a time. After each chunk every start's last
   section points are compared with the attractors found so far (*recurrence*): a start whose
   last ``max(2 n, confirm)`` points follow a period-``n`` attractor's points in phase order,
   each within ``recur_rtol`` of the attractor's scale, and themselves repeat after ``n``
   periods within ``recur_period_rtol`` (near the classifier's period test), or
   (``early_clouds`` only) whose last ``confirm_cloud`` points all fall in the (one-cell
   dilated) grid occupancy of a non-periodic attractor, is labelled and stops. A start that
   diverges is recorded as divergent.
   Every ``rescout`` periods the first still unlabelled start of each cell is promoted to a
   scout: its full-length run continues from where it is (so it is exactly its full-length
   run) and its motion joins the list the others are tested against.
3. Starts still unlabelled after ``transient`` periods continue into measurement and
   classification exactly as their full-length run would (same state, remaining transient 0),
   and their steady motions are merged into the list.

Finally every start's motion (its own full-length one, or the attractor it was labelled onto)
is merged again in a canonical order (continuation states, then starts by index), so the list
does not depend on the order in which starts happened to finish.

Merging and the last step: :mod:`gearsim.analysis.attractors.matching`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from gearsim.analysis.attractors.mapper import System, check_inputs
from gearsim.analysis.attractors.matching import KnownAttractors, assemble
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import CellAttractors, Steady


def map_attractors(
    system: System,
    starts: Sequence[np.ndarray],
    options: FinderOptions | None = None,
    *,
    continuation: Sequence[Mapping[str, np.ndarray | None]] | None = None,
    continuation_periods: Sequence[Mapping[str, int]] | None = None,
) -> list[CellAttractors]:
    """Attractors of the cells of ``system`` from the start states ``starts[c]`` (the
    :class:`~gearsim.analysis.attractors.mapper.AttractorMapper` signature).

    ``starts``: per cell a ``(K_c, d)`` array of start states (the basin samples);
    ``continuation``: per cell a mapping ``{"forward": state, "backward": state}`` (either may
    be missing or None), states on a continuation branch run with
    ``system.transient_continuation`` periods (their attractors get ``found_by`` forward /
    backward); ``continuation_periods``: the absolute period index of each (forcing not
    T-periodic only). ``options`` (:class:`FinderOptions`; ``period_rtol`` None is the
    classifier's 1e-5): ``scouts`` random starts per cell get full-length runs first, and every
    ``rescout`` probed periods the first still unlabelled start of each cell gets its
    full-length run too; ``early=False``: every start its full-length run.
    """
    opts = (options or FinderOptions()).resolved(1e-5)
    early = opts.early
    n_cells = check_inputs(starts, continuation)
    known = [KnownAttractors(opts) for _ in range(n_cells)]
    starts = [np.atleast_2d(np.asarray(s, dtype=float)) for s in starts]
    K = [len(s) for s in starts]
    labels = [np.full(k, -2, dtype=np.int64) for k in K]  # -2 not yet known
    is_early = [np.zeros(k, dtype=bool) for k in K]
    periods_run = [np.zeros(k, dtype=np.int64) for k in K]
    cont_labels: list[dict[str, int]] = [{} for _ in range(n_cells)]
    cont_steady: list[list[tuple[str, Steady]]] = [[] for _ in range(n_cells)]
    cont_found: list[dict[int, set[str]]] = [{} for _ in range(n_cells)]

    # 1. continuation states (full-length runs with the continuation transient)
    if continuation is not None:
        ct = int(system.transient_continuation)
        cells, states, names, k0 = [], [], [], []
        for c, m in enumerate(continuation):
            for name, y in (m or {}).items():
                if y is None:
                    continue
                cells.append(c)
                states.append(np.asarray(y, dtype=float))
                names.append(name)
                k0.append(0 if continuation_periods is None
                          else int(continuation_periods[c].get(name, 0)))  # fmt: skip
        if cells:
            res = system.steady(np.array(cells), np.array(states), ct, np.array(k0))
            for c, name, s in zip(cells, names, res, strict=True):
                cont_steady[c].append((name, s))
                a = known[c].add(s)
                cont_labels[c][name] = a
                if a >= 0:
                    cont_found[c].setdefault(a, set()).add(name)

    # 2. full-length runs of all starts, or scouts + recurrence
    T = int(system.transient)
    if not early:
        todo = [(c, i) for c in range(n_cells) for i in range(K[c])]
        _run_full(system, known, starts, labels, periods_run, todo, T)
    else:
        scout = [(c, i) for c in range(n_cells) for i in range(min(opts.scouts, K[c]))]
        _run_full(system, known, starts, labels, periods_run, scout, T)
        _probe(system, known, starts, labels, is_early, periods_run, opts, T)

    # 3. merge again in a canonical order, basin fractions
    return assemble(opts, starts, labels, is_early, periods_run, known, cont_steady)




def _run_full(system, known, starts, labels, periods_run, todo, transient, states=None,
              done=None) -> None:
    """Full-length runs (from ``states`` after ``done`` periods, default: from the starts)."""
    if not todo:
        return
    cells = np.array([c for c, _ in todo])
    if states is None:
        states = np.array([starts[c][i] for c, i in todo])
        done = np.zeros(len(todo), dtype=np.int64)
    left = transient - int(done[0]) if len(done) else transient
    res = system.steady(cells, states, max(left, 0), done)
    for (c, i), s, d in zip(todo, res, done, strict=True):
        labels[c][i] = known[c].add(s)
        known[c].own[i] = s
        extra = int(s.info.get("periods", 0)) if s.info else 0
        periods_run[c][i] = int(d) + (extra if extra else max(left, 0))


def _probe(system, known, starts, labels, is_early, periods_run, opts: FinderOptions,
           T: int) -> None:
    """Advance the unlabelled starts chunk by chunk; label on recurrence; finish the rest."""
    todo = [(c, i) for c in range(len(starts)) for i in range(len(starts[c])) if labels[c][i] == -2]
    if not todo:
        return
    d = starts[todo[0][0]].shape[1]
    n_top = max((s.period for k in known for s in k.steadies), default=1)
    L = max(opts.confirm_cloud, opts.confirm + n_top, 3 * n_top)
    cells = np.array([c for c, _ in todo])
    states = np.array([starts[c][i] for c, i in todo])
    hist = np.full((len(todo), L, d), np.nan)
    filled = np.zeros(len(todo), dtype=np.int64)
    done = 0
    active = np.arange(len(todo))
    while len(active) and done < T:
        m = min(opts.chunk, T - done)
        secs, finals, div = system.advance(
            cells[active], states[active], m, np.full(len(active), done, dtype=np.int64)
        )
        done += m
        states[active] = finals
        hist[active] = np.concatenate([hist[active], secs[:, :, :d]], axis=1)[:, -L:]
        filled[active] = np.minimum(filled[active] + m, L)
        keep = np.ones(len(active), dtype=bool)
        for r, t in enumerate(active):
            if div[r]:
                c, i = todo[t]
                labels[c][i] = -1
                periods_run[c][i] = done
                keep[r] = False
        # recurrence onto the attractors known so far, per cell
        alive = active[keep]
        for c in np.unique(cells[alive]):
            if not known[c].steadies:
                continue
            rows = alive[cells[alive] == c]
            hit = known[c].recur(hist[rows], filled[rows])
            for t, a in zip(rows, hit, strict=True):
                if a >= 0:
                    cc, i = todo[t]
                    labels[cc][i] = a
                    is_early[cc][i] = True
                    periods_run[cc][i] = done
        active = np.array([t for t in active if labels[todo[t][0]][todo[t][1]] == -2],
                          dtype=np.int64)
        if len(active) and opts.rescout and done % opts.rescout == 0 and done < T:
            # a new scout per cell that still has unlabelled starts: its full-length run
            # (continued from where it is) may reveal the attractor the others approach
            first: dict[int, int] = {}
            for t in active:
                first.setdefault(int(cells[t]), int(t))
            picks = np.array(sorted(first.values()), dtype=np.int64)
            _run_full(system, known, starts, labels, periods_run, [todo[t] for t in picks], T,
                      states=states[picks], done=np.full(len(picks), done, dtype=np.int64))
            active = np.setdiff1d(active, picks)
    if len(active):
        rest = [todo[t] for t in active]
        _run_full(system, known, starts, labels, periods_run, rest, T, states=states[active],
                  done=np.full(len(active), done, dtype=np.int64))


