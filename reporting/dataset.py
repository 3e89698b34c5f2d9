"""The dataset report: every subject side by side, parameter ranges across the population, and one
summary table (CSV) of every figure."""
from __future__ import annotations

import csv
import html
import io
import json
import os
from pathlib import Path

import numpy as np

from core.atomic import write_text_atomic
from ppm.parameters import PinnaParameters, parameter_specs

from .cost import solve_costs, subjects_timings
from .figures import distance_histogram, localisation_bars, parameter_deviation_figure
from .subject import STYLE, _image, read_distances

COLUMNS = ("subject", "align_median_mm", "align_p95_mm", "align_seconds", "remesh_ok", "triangles",
           "pinna_edge_median_mm", "qe_reference_percent", "pe_reference_deg", "qe_ppm_percent", "pe_ppm_deg",
           "sensitivity_db", "solve_seconds_reference", "solve_seconds_ppm", "all_stages_seconds")
PARAMETER_COLUMNS = ("parameter", "kind", "default", "lower", "upper", "min", "median", "max", "n_subjects")


def _load(path: Path) -> dict:
    return json.loads(path.read_text()) if path.is_file() else {}


def dataset_summary(results: str | os.PathLike, subjects: list[str],
                    timings_root: str | os.PathLike | None = None) -> list[dict]:
    """One row per subject with the figures of every stage (empty where a stage did not run); with
    ``timings_root`` (Snakemake benchmark files) also the solve and total seconds."""
    rows = []
    all_timings = subjects_timings(timings_root, subjects) if timings_root is not None else {}
    for subject in subjects:
        timings = all_timings.get(subject, [])
        base = Path(results) / subject
        solve = {c["variant"]: c["solve_seconds"] for c in solve_costs(base, timings)}
        align, remesh = _load(base / "align" / "summary.json"), _load(base / "remesh" / "validation.json")
        localisation = _load(base / "localisation" / "qe_pe.json")
        local = localisation.get("conditions", {})
        distance = align.get("distance_target_to_ppm", {})
        rows.append({
            "subject": subject, "align_median_mm": distance.get("median_mm"), "align_p95_mm": distance.get("p95_mm"),
            "align_seconds": align.get("seconds"), "remesh_ok": remesh.get("ok"), "triangles": remesh.get("n_triangles"),
            "pinna_edge_median_mm": remesh.get("pinna_edge_mm", {}).get("median"),
            "qe_reference_percent": local.get("reference", {}).get("qe_percent"),
            "pe_reference_deg": local.get("reference", {}).get("pe_deg"),
            "qe_ppm_percent": local.get("ppm", {}).get("qe_percent"), "pe_ppm_deg": local.get("ppm", {}).get("pe_deg"),
            "sensitivity_db": localisation.get("sensitivity_db"),
            "solve_seconds_reference": solve.get("reference"), "solve_seconds_ppm": solve.get("ppm"),
            "all_stages_seconds": round(sum(t.seconds for t in timings), 1) if timings else None})
    return rows


def parameter_ranges(parameters: dict[str, PinnaParameters]) -> list[dict]:
    """Per PPM parameter: its default and range, and the min / median / max fitted across the subjects."""
    matrix = np.array([p.to_vector() for p in parameters.values()])
    rows = []
    for i, spec in enumerate(parameter_specs()):
        rows.append({"parameter": spec.name, "kind": spec.kind, "default": spec.default, "lower": spec.lower,
                     "upper": spec.upper, "min": float(matrix[:, i].min()), "median": float(np.median(matrix[:, i])),
                     "max": float(matrix[:, i].max()), "n_subjects": len(matrix)})
    return rows


def _write_csv(path: str | os.PathLike, columns: tuple[str, ...], rows: list[dict]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(path, buffer.getvalue())


def _html_table(columns: tuple[str, ...], rows: list[dict]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{'' if r[c] is None else html.escape(f'{r[c]:.3f}' if isinstance(r[c], float) else str(r[c]))}</td>"
                                    for c in columns) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def write_dataset_report(results: str | os.PathLike, subjects: list[str], out_html: str | os.PathLike,
                         out_csv: str | os.PathLike, figures_dir: str | os.PathLike,
                         out_parameters_csv: str | os.PathLike | None = None, note: str = "",
                         timings_root: str | os.PathLike | None = None) -> Path:
    """Summary CSV (one row per subject), parameter ranges across the population (CSV), population figures
    (parameter deviations, distance histograms, QE/PE bars) and an HTML page linking the subject reports."""
    results, figures = Path(results), Path(figures_dir)
    figures.mkdir(parents=True, exist_ok=True)
    rows = dataset_summary(results, subjects, timings_root)
    _write_csv(out_csv, COLUMNS, rows)
    parameters = {s: PinnaParameters.read(results / s / "align" / "parameters.json", out_of_range="clip")
                  for s in subjects if (results / s / "align" / "parameters.json").is_file()}
    sections = [f"<h1>Dataset report ({len(subjects)} subjects)</h1>"]
    if note:
        sections.append(f"<p class='note'>{html.escape(note)}</p>")
    sections += ["<h2>Every figure per subject</h2>", _html_table(COLUMNS, rows),
                 "<ul>" + "".join(f"<li><a href='{html.escape(s)}/report.html'>{html.escape(s)}</a></li>"
                                  for s in subjects) + "</ul>"]
    if parameters:
        parameter_deviation_figure(parameters, figures / "parameter_deviations.png",
                                   "PPM parameter deviations across the dataset")
        distance_histogram({s: read_distances(results / s / "align" / "distances.ply") for s in parameters},
                           figures / "distance_histograms.png", "one-sided distances, all subjects")
        ranges = parameter_ranges(parameters)
        if out_parameters_csv is not None:
            _write_csv(out_parameters_csv, PARAMETER_COLUMNS, ranges)
        widest = sorted(ranges, key=lambda r: (r["max"] - r["min"]) / ((r["upper"] - r["lower"]) or 1.0))[::-1][:12]
        sections += ["<h2>Parameters across the population</h2>", _image(figures / "parameter_deviations.png"),
                     "<p>The twelve parameters that vary most across the subjects, relative to their range "
                     "(all 144 in the parameter CSV):</p>", _html_table(PARAMETER_COLUMNS, widest),
                     "<h2>One-sided distances</h2>", _image(figures / "distance_histograms.png")]
    if any(r["qe_ppm_percent"] is not None for r in rows):
        localisation_bars(rows, figures / "localisation_bars.png")
        sections += ["<h2>Predicted localisation</h2>", _image(figures / "localisation_bars.png")]
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Dataset report</title><style>{STYLE}</style>"
            f"</head><body>{''.join(sections)}</body></html>\n")
    return write_text_atomic(out_html, page)
