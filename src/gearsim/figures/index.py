"""The generated index ``results/figures/README.md``: every figure, the paper's caption, ours,
and where ours differs and why (collected from the ``figNN.json`` records the CLI writes)."""

from __future__ import annotations

import json
from pathlib import Path

from .registry import ALL, PAPER_CAPTIONS


def write_index(outdir: str | Path, out: str | Path | None = None) -> Path:
    """Write the index of the figures in ``outdir``; figures not built yet are listed as such."""
    outdir = Path(outdir)
    out = Path(out) if out else outdir / "README.md"
    lines = [
        "# Figures of the study (generated)",
        "",
        "Written by `gearsim figures --index`; do not edit. Each entry: the paper's caption, "
        "ours, and where ours differs and why. Images: PNG (200 dpi) and PDF.",
        "",
    ]
    for n in ALL:
        rec_path = outdir / f"fig{n:02d}.json"
        lines.append(f"## Fig {n}")
        lines.append("")
        lines.append(f"**Paper:** {PAPER_CAPTIONS[n]}")
        lines.append("")
        if not rec_path.is_file():
            lines += ["*Not built yet.*", ""]
            continue
        rec = json.loads(rec_path.read_text())
        files = ", ".join(f"[{Path(f).name}]({Path(f).name})" for f in rec.get("files", []))
        lines.append(f"**Ours:** {rec['caption']} ({files})")
        lines.append("")
        if rec.get("inputs"):
            lines.append(f"Inputs: {', '.join(rec['inputs'])}.")
            lines.append("")
        if rec.get("differences"):
            lines.append("**Differences from the paper and why:**")
            lines.append("")
            lines += [f"- {d}" for d in rec["differences"]]
            lines.append("")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines))
    return out
