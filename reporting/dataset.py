"""The dataset report: every subject side by side, parameter ranges across the population, and one
summary table (CSV) of every figure."""
from __future__ import annotations

import csv
import html
import io
import json
import os
from pathlib import Path

from ppm.atomic import write_text_atomic
from ppm.parameters import PinnaParameters

from .figures import distance_histogram, parameter_deviation_figure
from .subject import STYLE, _image, read_distances

COLUMNS = ("subject", "align_median_mm", "align_p95_mm", "align_seconds", "remesh_ok", "triangles",
           "pinna_edge_median_mm", "qe_reference_percent", "pe_reference_deg", "qe_ppm_percent", "pe_ppm_deg",
           "sensitivity_db")


def _load(path: Path) -> dict:
    return json.loads(path.read_text()) if path.is_file() else {}


def dataset_summary(results: str | os.PathLike, subjects: list[str]) -> list[dict]:
    """One row per subject with the figures of every stage (empty where a stage did not run)."""
    rows = []
    for subject in subjects:
        base = Path(results) / subject
        align, remesh = _load(base / "align" / "summary.json"), _load(base / "remesh" / "validation.json")
        local = _load(base / "localisation" / "qe_pe.json").get("conditions", {})
        distance = align.get("distance_target_to_ppm", {})
        rows.append({
            "subject": subject, "align_median_mm": distance.get("median_mm"), "align_p95_mm": distance.get("p95_mm"),
            "align_seconds": align.get("seconds"), "remesh_ok": remesh.get("ok"), "triangles": remesh.get("n_triangles"),
            "pinna_edge_median_mm": remesh.get("pinna_edge_mm", {}).get("median"),
            "qe_reference_percent": local.get("reference", {}).get("qe_percent"),
            "pe_reference_deg": local.get("reference", {}).get("pe_deg"),
            "qe_ppm_percent": local.get("ppm", {}).get("qe_percent"), "pe_ppm_deg": local.get("ppm", {}).get("pe_deg"),
            "sensitivity_db": _load(base / "localisation" / "qe_pe.json").get("sensitivity_db")})
    return rows


def write_dataset_report(results: str | os.PathLike, subjects: list[str], out_html: str | os.PathLike,
                         out_csv: str | os.PathLike, figures_dir: str | os.PathLike) -> Path:
    """Summary CSV, population figures and an HTML page linking the subject reports."""
    results, figures = Path(results), Path(figures_dir)
    figures.mkdir(parents=True, exist_ok=True)
    rows = dataset_summary(results, subjects)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(out_csv, buffer.getvalue())
    parameters = {s: PinnaParameters.read(results / s / "align" / "parameters.json", out_of_range="clip")
                  for s in subjects if (results / s / "align" / "parameters.json").is_file()}
    if parameters:
        parameter_deviation_figure(parameters, figures / "parameter_deviations.png",
                                   "PPM parameter deviations across the dataset")
        distance_histogram({s: read_distances(results / s / "align" / "distances.ply") for s in parameters},
                           figures / "distance_histograms.png", "one-sided distances, all subjects")
    head = "".join(f"<th>{html.escape(c)}</th>" for c in COLUMNS)
    body = "".join("<tr>" + "".join(f"<td>{'' if r[c] is None else html.escape(f'{r[c]:.3f}' if isinstance(r[c], float) else str(r[c]))}</td>"
                                    for c in COLUMNS) + "</tr>" for r in rows)
    links = "".join(f"<li><a href='{html.escape(s)}/report.html'>{html.escape(s)}</a></li>" for s in subjects)
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Dataset report</title><style>{STYLE}</style>"
            f"</head><body><h1>Dataset report ({len(subjects)} subjects)</h1><table><tr>{head}</tr>{body}</table>"
            f"<ul>{links}</ul>{_image(figures / 'parameter_deviations.png')}"
            f"{_image(figures / 'distance_histograms.png')}</body></html>\n")
    return write_text_atomic(out_html, page)
