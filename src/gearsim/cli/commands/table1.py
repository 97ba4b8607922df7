"""``gearsim table1``: the reconstructed Table 1 (standard parameters) as Markdown and CSV."""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from gearsim.dynamics.parameters import ParameterError
from gearsim.safe_yaml import load_yaml

NAME = "table1"
HELP = "write the reconstructed Table 1 (value, unit, provenance of every parameter)"

SECTIONS = ("dimensional", "derived", "dimensionless")


def table(path: str | Path) -> pd.DataFrame:
    """Rows ``section, name, value, unit, provenance, note`` of a standard-parameter file."""
    doc = load_yaml(path)
    if not isinstance(doc, dict) or "dimensionless" not in doc:
        raise ParameterError(f"{path}: expected a mapping with key 'dimensionless'")
    rows = []
    for sec in SECTIONS:
        part = doc.get(sec) or {}
        if not isinstance(part, dict):
            raise ParameterError(
                f"{path}: key '{sec}' must be a mapping of parameter names, "
                f"got {type(part).__name__}"
            )
        for name, e in part.items():
            e = e if isinstance(e, dict) else {"value": e}
            rows.append({"section": sec, "name": name, "value": e.get("value"),
                         "unit": e.get("unit", "-" if sec == "dimensionless" else ""),
                         "provenance": e.get("provenance", ""), "note": e.get("note", "")})
    return pd.DataFrame(rows)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def markdown(df: pd.DataFrame, title: str = "Table 1 (reconstructed)") -> str:
    lines = [f"# {title}", ""]
    for sec in SECTIONS:
        part = df[df["section"] == sec]
        if not len(part):
            continue
        lines += [f"## {sec}", "", "| parameter | value | unit | provenance | note |",
                  "|---|---|---|---|---|"]
        for r in part.itertuples():
            note = str(r.note).replace("|", "/")
            lines.append(f"| {r.name} | {_fmt(r.value)} | {r.unit} | {r.provenance} | {note} |")
        lines.append("")
    return "\n".join(lines)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--params", default="config/standard_parameters.yaml",
                   help="standard-parameter file to tabulate")
    p.add_argument("--md", default="results/table1.md", help="Markdown output")
    p.add_argument("--csv", default="results/table1.csv", help="CSV output")


def run(args: argparse.Namespace) -> int:
    from gearsim.study.preflight import check_outputs, write_text_atomic

    df = table(args.params)
    check_outputs([args.md, args.csv])
    for path, text in ((args.md, markdown(df)), (args.csv, df.to_csv(index=False))):
        out = write_text_atomic(Path(path), text)
        print(f"wrote {out}")
    return 0
