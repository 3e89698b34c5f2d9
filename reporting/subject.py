"""The per-subject report: one self-contained HTML page (figures embedded) from the outputs the
workflow made for a subject (alignment, stitching/remeshing, localisation); missing stages are named
as not run rather than left out silently."""
from __future__ import annotations

import base64
import html
import json
import os
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import write_text_atomic
from ppm.parameters import PinnaParameters, parameter_specs

from .cost import solve_costs, subject_timings
from .figures import GROUPS, distance_histogram, group_indices, parameter_deviation_figure, parameter_recovery_figure


def _image(path: Path) -> str:
    if not path.is_file():
        return f"<p class='missing'>{html.escape(path.name)}: not made</p>"
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f"<img alt='{html.escape(path.name)}' src='data:image/png;base64,{data}'>"


def _table(rows: list[tuple[str, str]]) -> str:
    return "<table>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows) + "</table>"


def _json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def read_distances(path: str | os.PathLike) -> np.ndarray:
    """Per-point distances (mm) stored as vertex quality in ``distances.ply``."""
    cloud = trimesh.load(path, process=False)
    quality = cloud.metadata.get("_ply_raw", {}).get("vertex", {}).get("data", {})
    if hasattr(quality, "dtype") and "quality" in quality.dtype.names:
        return np.asarray(quality["quality"], dtype=np.float64)
    return np.asarray(cloud.vertex_attributes["quality"], dtype=np.float64)


STYLE = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222} img{max-width:100%} "
         "table{border-collapse:collapse;margin:.5em 0} th,td{border:1px solid #ccc;padding:3px 8px;text-align:left} "
         ".missing{color:#a00} .note{background:#fff3cd;padding:.5em}")


def parameter_recovery(fitted: PinnaParameters, truth: PinnaParameters) -> list[dict]:
    """Absolute error of the fitted parameters per group (locations mm, rotations deg, scales, shape-key
    weights): median and maximum over the group, and the parameter with the maximum."""
    specs = parameter_specs()
    error = np.abs(fitted.to_vector() - truth.to_vector())
    rows = []
    for kind, label in GROUPS:
        chosen = group_indices(kind)
        worst = max(chosen, key=lambda i: error[i])
        rows.append({"group": label, "n": len(chosen), "median": float(np.median(error[chosen])),
                     "max": float(error[worst]), "worst": specs[worst].name})
    return rows


def _recovery_section(fitted: PinnaParameters, truth: PinnaParameters, figures: Path, subject: str) -> list[str]:
    parameter_recovery_figure(truth, fitted, figures / "parameter_recovery.png",
                              f"{subject}: fitted vs true parameters (deviation from the default)")
    rows = [(r["group"], f"median {r['median']:.3f}, max {r['max']:.3f} ({r['worst']})")
            for r in parameter_recovery(fitted, truth)]
    return ["<h2>Recovery of the true parameters (demo subject)</h2>",
            "<p>Absolute error of the fitted parameters against the parameters the demo ear was made with.</p>",
            _table(rows), _image(figures / "parameter_recovery.png")]


def _cost_section(results: Path, timings_root: Path, subject: str) -> list[str]:
    timings = subject_timings(timings_root, subject)
    if not timings:
        return ["<h2>Cost of each stage</h2>", "<p class='missing'>no benchmark files found</p>"]
    rows = [(f"{t.rule} ({t.job})", f"{t.seconds:.1f} s" + (f", peak {t.max_rss_mb:.0f} MB" if t.max_rss_mb else ""))
            for t in timings]
    rows.append(("all stages", f"{sum(t.seconds for t in timings):.1f} s"))
    solve_rows = [(f"HRTF solve, {c['variant']} head",
                   f"{c['solver']}, {c['elements']} elements, {c['frequencies']} frequencies, {c['solve_seconds']} s"
                   + (f" ({c['seconds_per_frequency']} s per frequency, both ears)" if c["seconds_per_frequency"] else ""))
                  for c in solve_costs(results, timings)]
    return ["<h2>Cost of each stage</h2>", "<p>Wall-clock time and peak memory of each job (Snakemake benchmark "
            f"files in {html.escape(str(timings_root))}).</p>", _table(solve_rows + rows)]


def write_subject_report(subject: str, results: str | os.PathLike, out_html: str | os.PathLike,
                         figures_dir: str | os.PathLike, note: str = "", truth: str | os.PathLike | None = None,
                         timings_root: str | os.PathLike | None = None) -> Path:
    """Build the figures into ``figures_dir`` and the HTML page ``out_html`` for one subject.

    ``note`` is shown first (the demo's fidelity warning); ``truth`` (parameters the subject's ear was made
    with, demo only) adds a parameter-recovery section; ``timings_root`` (Snakemake benchmark files) a cost
    section."""
    results, figures = Path(results), Path(figures_dir)
    figures.mkdir(parents=True, exist_ok=True)
    sections = [f"<h1>Subject {html.escape(subject)}</h1>"]
    if note:
        sections.append(f"<p class='note'>{html.escape(note)}</p>")
    align = _json(results / "align" / "summary.json")
    sections.append("<h2>Alignment of the PPM to the pinna scan</h2>")
    if align:
        parameters = PinnaParameters.read(results / "align" / "parameters.json", out_of_range="clip")
        parameter_deviation_figure({subject: parameters}, figures / "parameter_deviations.png",
                                   f"{subject}: PPM parameters minus default")
        distances = read_distances(results / "align" / "distances.ply")
        distance_histogram({subject: distances}, figures / "distance_histogram.png",
                           f"{subject}: one-sided distance, every scan point to the aligned PPM")
        d = align.get("distance_target_to_ppm", {})
        sections.append(_table([(k, f"{v:.3f}" if isinstance(v, float) else str(v)) for k, v in d.items()]
                               + [("warnings", "; ".join(align.get("warnings", [])) or "none")]))
        sections += [_image(figures / "parameter_deviations.png"), _image(figures / "distance_histogram.png"),
                     _image(results / "align" / "distance_map.png")]
    else:
        sections.append("<p class='missing'>not run</p>")
    if align and truth is not None:
        sections += _recovery_section(parameters, PinnaParameters.read(truth, out_of_range="clip"), figures, subject)
    remesh = _json(results / "remesh" / "validation.json")
    sections.append("<h2>Head with the PPM pinna: seam and BEM mesh</h2>")
    if remesh:
        sections.append(_table([
            ("closed / manifold / self-intersecting faces",
             f"{remesh['closed']} / {remesh['manifold']} / {remesh['self_intersecting_faces']}"),
            ("triangles", str(remesh["n_triangles"])),
            ("pinna edge median (p95) mm", f"{remesh['pinna_edge_mm']['median']:.3f} ({remesh['pinna_edge_mm']['p95']:.3f})"),
            ("PPM pinna to final head, p95 / max mm",
             f"{remesh['pinna_to_head_mm']['p95']:.4f} / {remesh['pinna_to_head_mm']['max']:.3f}"),
            ("6 elements per wavelength up to (pinna / whole head)",
             f"{remesh['max_frequency_hz_6_per_wavelength_pinna']:.0f} Hz / {remesh['max_frequency_hz_6_per_wavelength']:.0f} Hz"),
            ("ear-canal source elements", json.dumps(remesh.get("ear_elements", {})))]))
    else:
        sections.append("<p class='missing'>not run</p>")
    localisation = _json(results / "localisation" / "qe_pe.json")
    sections.append("<h2>Predicted localisation (baumgartner2014)</h2>")
    if localisation:
        rows = [("sensitivity S (dB)", f"{localisation['sensitivity_db']:.3f} "
                 f"(reference calibrated to {localisation['calibration_qe_percent']} % QE)")]
        if "calibration_note" in localisation:
            rows.append(("calibration NOT reached", localisation["calibration_note"]))
        if "frequency_set" in localisation:
            frequency_set = localisation["frequency_set"]
            rows.append(("frequencies solved", frequency_set["description"]
                         + ("; the reference HRIRs sampled at the same set and rebuilt the same way"
                            if frequency_set.get("reference_rebuilt_at_set") else "")))
        rows += [(name, f"QE {c['qe_percent']:.2f} %, PE {c['pe_deg']:.2f} deg")
                 for name, c in localisation["conditions"].items()]
        sections.append(_table(rows))
        sections += [_image(results / "localisation" / name) for name in
                     ("qe_pe_bars.png", "reference_matrix.png", "ppm_matrix.png")]
    else:
        sections.append("<p class='missing'>not run (HRTFs off: set hrtf.enabled in the config)</p>")
    if timings_root is not None:
        sections += _cost_section(results, Path(timings_root), subject)
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(subject)}</title>"
            f"<style>{STYLE}</style></head><body>{''.join(sections)}</body></html>\n")
    return write_text_atomic(out_html, page)
