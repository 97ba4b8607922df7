"""A plane's audit file: the sample of its cells re-simulated at tightened tolerance
(:func:`gearsim.study.audit.audit_frame`) written with its provenance, agreement and threshold."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from gearsim.results.parquet import PROVENANCE_KEY, now_iso, write_parquet


def audit_plane(study, plane: str, cells_file: str | Path, out: str | Path,
                progress: Any = None) -> tuple[int, float, float]:
    """Audit ``plane`` from its ``cells.parquet`` into ``out``. ``progress(total)``: a progress
    bar factory (``None``: silent). Returns ``(cells audited, agreement, threshold)``."""
    import pandas as pd

    from gearsim.study import provenance
    from gearsim.study.audit import audit_frame, audit_settings

    config = study.config
    cells = pd.read_parquet(cells_file)
    started, t0 = now_iso(), time.perf_counter()
    bar = progress(max(1, int(config["audit"]["fraction"] * len(cells)))) if progress else None
    df = audit_frame(study, plane, cells, bar)
    if bar is not None:
        bar.close()
    agreement = float(df["agree"].mean()) if len(df) else float("nan")
    threshold = float(config["audit"]["threshold"])
    subtree = {**provenance.plane_subtree(study, plane), "audit": dict(config["audit"])}
    prov = provenance.provenance(
        subtree, kind="audit", name=plane, study=study, started=started, finished=now_iso(),
        wall_s=time.perf_counter() - t0, cells=len(df), audit_seed=int(config["audit"]["seed"]),
        agreement=agreement, threshold=threshold, settings=audit_settings(study).to_dict(),
        workers="in-process",
    )
    write_parquet(df, out, {PROVENANCE_KEY: prov})
    return len(df), agreement, threshold
