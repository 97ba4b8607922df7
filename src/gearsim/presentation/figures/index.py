"""The generated index ``results/figures/README.md``: every figure the study drew, the paper's
caption, ours, and where ours differs and why (collected from the ``figNN.json`` records the CLI
writes), then the maps of every plane and the diagram of every sweep. A figure the study did not
draw is not listed."""

from __future__ import annotations

import json
from pathlib import Path

from gearsim.presentation.figures.registry import figures


def write_index(outdir: str | Path, out: str | Path | None = None) -> Path:
    """Write the index of the figures in ``outdir`` (only those drawn: their records exist)."""
    outdir = Path(outdir)
    out = Path(out) if out else outdir / "README.md"
    lines = [
        "# Figures of the study (generated)",
        "",
        "Written by `gearsim figures --index`; do not edit. Each entry of a paper figure: the "
        "paper's caption, ours, and where ours differs and why. Images: PNG (200 dpi) and PDF.",
        "",
    ]
    recs = [json.loads(p.read_text()) for p in sorted(outdir.glob("fig[0-9][0-9].json"))]
    settings = [r["integration"] for r in recs if r.get("integration")]
    params = [r["parameters"] for r in recs if r.get("parameters")]
    if settings:
        same = all(s == settings[0] for s in settings) and all(p == params[0] for p in params)
        lines.append("Drawn with the pipeline config's integration settings "
                     + ("(the same for every figure)" if same else
                        "(they differ between figures: see each figNN.json)") + ":")
        lines.append("")
        lines.append("`" + ", ".join(f"{k}={v}" for k, v in settings[0].items()) + "`")
        lines.append("")
        lines.append("and the parameters `" + ", ".join(
            f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in params[0].items()) + "` (the sweeps and planes fix w, b or xi).")
        lines.append("")
    for n, spec in figures().items():
        rec_path = outdir / f"fig{n:02d}.json"
        if not rec_path.is_file():  # not drawn by this study
            continue
        lines.append(f"## Fig {n}")
        lines.append("")
        lines.append(f"**{'Paper' if spec.in_paper else 'Shows'}:** {spec.paper_caption}")
        lines.append("")
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
    lines += _map_lines(outdir)
    lines += _sweep_lines(outdir)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines))
    return out


def _map_lines(outdir: Path) -> list[str]:
    """The maps of every plane (``planes/<plane>-<kind>.json``), one section per plane."""
    from gearsim.presentation.figures.maps import PLANE_MAPS

    order = {k: n for n, k in enumerate(PLANE_MAPS)}
    recs = [json.loads(p.read_text()) for p in sorted((outdir / "planes").glob("*.json"))]
    recs.sort(key=lambda r: (r["plane"], order.get(r["map"], len(order)), r["map"]))
    if not recs:
        return []
    lines = ["# Maps of every plane", "",
             "Drawn for each plane of the study whatever its two axes (`gearsim figures "
             "--maps`).", ""]
    for plane in dict.fromkeys(r["plane"] for r in recs):
        lines += [f"## Plane {plane}", ""]
        for r in (r for r in recs if r["plane"] == plane):
            files = ", ".join(f"[{Path(f).name}](planes/{Path(f).name})" for f in r["files"])
            lines.append(f"- **{r['title']}** ({files}): {r['caption']}")
            lines += [f"  - {n}" for n in r.get("notes", [])]
        lines.append("")
    return lines


def _sweep_lines(outdir: Path) -> list[str]:
    """The bifurcation diagram of every sweep (``sweeps/<sweep>.json``)."""
    recs = [json.loads(p.read_text()) for p in sorted((outdir / "sweeps").glob("*.json"))]
    if not recs:
        return []
    lines = ["# Bifurcation diagrams of every sweep", "",
             "Section points, DC and Kmax against the swept value, in the sweep's own units "
             "(`gearsim figures --sweep-diagrams`).", ""]
    for r in recs:
        files = ", ".join(f"[{Path(f).name}](sweeps/{Path(f).name})" for f in r["files"])
        lines.append(f"- **{r['title']}** ({files}): {r['caption']}")
    lines.append("")
    return lines
