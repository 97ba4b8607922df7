"""The report states the numerical audit and warns loudly when it is below its threshold."""

import pandas as pd

from gearsim.presentation.report import Report
from gearsim.presentation.report_inputs import load_audits
from gearsim.presentation.report_markdown import to_markdown
from gearsim.results.catalogue import PROVENANCE_KEY, write_parquet


def _audit_file(root, plane, agreement, threshold=0.95):
    df = pd.DataFrame({"agree": [True, False]})
    write_parquet(df, root / plane / "audit.parquet",
                  {PROVENANCE_KEY: {"cells": 2, "agreement": agreement, "threshold": threshold}})


def test_audit_section_and_warning(tmp_path):
    _audit_file(tmp_path, "wb", 1.0)
    _audit_file(tmp_path, "wxi", 0.5)
    audits = load_audits(tmp_path, ["wb", "wxi", "missing"])
    assert [a["plane"] for a in audits] == ["wb", "wxi"]
    md = to_markdown(Report(audit=audits))
    assert "## Numerical audit" in md and "| wb | 2 | 1.000 | 0.95 |" in md
    assert "WARNING" in md and "below its threshold on wxi" in md
    ok = to_markdown(Report(audit=audits[:1]))
    assert "WARNING" not in ok
