"""The dataset evaluation (the paper's Figures 6 and 7 for a dataset): per subject and condition the predicted
localisation (baumgartner2014, reference as template, S calibrated on the reference), the distances between
the target scan and the condition's pinna, and the cost of solving; written as summary.csv, the solved
left-ear HRTFs, two figures, an HTML page and a README into one folder kept in the repository.

Distances are in millimetres: target -> model is the paper's one-sided Hausdorff distance (every scan point to
the pinna surface); model -> target is every model vertex to the scan surface, over the scanned region only
(:func:`ppm.align.report.reverse_distances_mm`).
"""
from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from core.atomic import atomic_path, write_text_atomic

#: Columns of summary.csv, in order (the issue's, the paper's protocol (reporting.paper_protocol.PAPER_COLUMNS), then
#: provenance).
COLUMNS = ("subject", "condition", "qe_percent", "pe_deg", "eb_deg", "sensitivity_db", "delta_qe_pp", "delta_pe_deg",
           "delta_qe_vs_original_pp", "delta_pe_vs_original_deg", "distance_median_mm", "distance_p95_mm",
           "reverse_median_mm", "reverse_p95_mm", "qe_paper_percent", "pe_paper_deg", "delta_qe_paper_pp",
           "delta_pe_paper_deg", "n_frequencies", "solve_cpu_hours", "n_elements", "steps_solved_here", "steps_restored", "head_sha256", "solver")

#: The evaluation's goals: |ΔQE| (pp) and |ΔPE| (deg) per condition, judged first by the paper's protocol (the
#: unchanged head solved here, ``original``, as reference and template: ``delta_*_paper``), and also against the
#: dataset's HRIRs and, where the subject has ``original``, against that head with the dataset's template.
GOALS = {"ppm": (2.0, 2.0), "own_pinna": (1.0, 1.0), "ppm_detail": (1.0, 1.0), "ppm_detail_hard": (2.0, 2.0)}

#: A condition that must also come nearer ``original`` (paper's protocol, |ΔQE| and |ΔPE|) than each of these.
NEARER_THAN = {"ppm_detail_hard": ("ppm_hard", "nricp_hard")}

CONDITION_LABELS = {"reference": "reference (dataset HRIRs, rebuilt at the set)", "ppm": "PPM (aligned, LOO template)",
                    "own_pinna": "own pinna (stitch + remesh control)", "default_ppm": "default PPM (global pose only)",
                    "ppm_detail": "PPM with its personal-detail layer",
                    "ppm_hard": "PPM fitted to the fixed defective scan",
                    "ppm_detail_hard": "the same with its personal-detail layer towards the defective scan",
                    "nricp_hard": "the template deformed by non-rigid ICP onto the defective scan",
                    "scan_hard": "the defective scan made watertight (screened Poisson), cut to the pinna",
                    "original": "original head (the reference head solved here)"}


def condition_distances(target_path: str | os.PathLike, pinna_path: str | os.PathLike,
                        summary_path: str | os.PathLike, points_path: str | os.PathLike, reach_mm: float = 10.0) -> dict:
    """Target -> model and model -> target distances (mm) of one condition, the model being the surface that was
    solved (the condition's final head mesh; a pinna mesh works the same): a JSON summary and the per-point values
    (npz: ``target_to_model`` per scan point, ``model_to_target`` per model vertex, ``counted`` mask). Model ->
    target counts the vertices within ``reach_mm`` of the scan whose closest scan point lies away from the scan's
    boundary (the rest of a head is not compared with a pinna scan)."""
    import trimesh  # noqa: PLC0415

    from ppm.align.report import distance_summary, one_sided_distances_mm, reverse_distances_mm  # noqa: PLC0415
    from ppm.align.target import prepare_target  # noqa: PLC0415

    target = prepare_target(target_path, side="left", segment=False)
    pinna = trimesh.load(pinna_path, process=False, force="mesh")
    if len(pinna.faces) == 0:
        raise ValueError(f"{pinna_path}: no faces; give the condition's pinna surface (mm)")
    from scipy.spatial import cKDTree  # noqa: PLC0415

    forward = one_sided_distances_mm(target, pinna.vertices, pinna.faces)
    # only model vertices near the scan are compared (a head's far side would cost gigabytes of candidates)
    near = np.isfinite(cKDTree(target.points_mm).query(pinna.vertices, distance_upper_bound=reach_mm + 2.0)[0])
    reverse = np.full(len(pinna.vertices), np.inf)
    counted = np.zeros(len(pinna.vertices), dtype=bool)
    if near.any():
        reverse[near], counted[near] = reverse_distances_mm(target, pinna.vertices[near])
    counted &= reverse <= reach_mm
    if not counted.any():
        raise ValueError(f"{pinna_path}: no vertex of the pinna lies over the scanned region of {target_path}; "
                         "is it placed at this subject's left ear?")
    summary = {"target": str(target_path), "pinna": str(pinna_path),
               "target_to_model": distance_summary(forward),
               "model_to_target": distance_summary(reverse[counted]),
               "model_vertices_counted": int(counted.sum()), "model_vertices": int(len(counted)), "reach_mm": reach_mm}
    buffer = io.BytesIO()
    np.savez_compressed(buffer, target_to_model=forward, model_to_target=reverse, counted=counted,
                        target_points_mm=target.points_mm)
    with atomic_path(points_path) as tmp:
        Path(tmp).write_bytes(buffer.getvalue())
    write_text_atomic(summary_path, json.dumps(summary, indent=2) + "\n")
    return summary


def solve_cost(status_files: list[str | os.PathLike], store: str | os.PathLike | None) -> dict:
    """Seconds of solving recorded by the step jobs' statuses; restored steps count with the seconds kept in
    the step store (where they were solved), so the total is the CPU time of the result, wherever it was made."""
    from mesh2hrtf_io.step_store import solve_seconds, stored_status  # noqa: PLC0415

    seconds, solved, restored, solvers = 0.0, 0, 0, set()
    for path in map(Path, status_files):
        statuses = json.loads(path.read_text())
        source = int(path.parent.name.split("_")[-1]) if path.parent.name.startswith("source_") else 1
        if "projects" in statuses:  # the embedded solver's job status
            solvers.add(f"embedded ({statuses.get('backend', {}).get('backend', statuses.get('device', '?'))})")
        for status in statuses.get("steps", [statuses]):
            if "restored_from" in status:
                restored += 1
                kept = stored_status(status["restored_from"], source, status["step"])
                seconds += solve_seconds(kept)
                solvers.add((kept or {}).get("solver") or status.get("solver") or "NumCalc")
            else:
                solved += 1
                seconds += solve_seconds(status)
                if "projects" not in statuses:
                    solvers.add(status.get("solver") or "NumCalc")
    return {"seconds": seconds, "steps_solved_here": solved, "steps_restored": restored,
            "solver": " + ".join(sorted(solvers))}


def evaluation_rows(results: str | os.PathLike, subjects: list[str], conditions: dict[str, list[str]],
                    heads: dict[tuple[str, str], str], steps: dict[tuple[str, str], list[str]],
                    store: str | os.PathLike | None = None) -> list[dict]:
    """One row per subject and condition (the reference first) with the columns of :data:`COLUMNS`."""
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415
    from mesh2hrtf_io.step_store import file_sha256  # noqa: PLC0415

    results = Path(results)
    rows = []
    for subject in subjects:
        localisation = json.loads((results / subject / "localisation" / "qe_pe.json").read_text())
        predicted = localisation["conditions"]
        reference = predicted["reference"]
        original = predicted.get("original") if "original" in conditions[subject] else None
        n_frequencies = len(localisation.get("frequency_set", {}).get("frequencies_hz", [])) or None
        missing = [c for c in ["reference", *conditions[subject]] if c not in predicted]
        if missing:
            raise ValueError(f"{results / subject / 'localisation' / 'qe_pe.json'} has no prediction for "
                             f"{', '.join(missing)} (made before the condition was configured): rerun the rule "
                             f"localisation for {subject} (e.g. snakemake --forcerun localisation)")
        for condition in ["reference", *conditions[subject]]:
            p = predicted[condition]
            row = {"subject": subject, "condition": condition, "qe_percent": p["qe_percent"], "pe_deg": p["pe_deg"],
                   "eb_deg": p["eb_deg"], "sensitivity_db": localisation["sensitivity_db"],
                   "delta_qe_pp": p["qe_percent"] - reference["qe_percent"],
                   "delta_pe_deg": p["pe_deg"] - reference["pe_deg"], "n_frequencies": n_frequencies}
            if original is not None and condition not in ("reference", "original"):
                row.update(delta_qe_vs_original_pp=p["qe_percent"] - original["qe_percent"],
                           delta_pe_vs_original_deg=p["pe_deg"] - original["pe_deg"])
            if condition != "reference":
                distances = json.loads((results / subject / "evaluation" / condition / "distances.json").read_text())
                cost = solve_cost(steps[subject, condition], Path(store) / subject / condition if store else None)
                project = read_project(results / subject / "hrtf" / condition / "project")
                row.update(distance_median_mm=distances["target_to_model"]["median_mm"],
                           distance_p95_mm=distances["target_to_model"]["p95_mm"],
                           reverse_median_mm=distances["model_to_target"]["median_mm"],
                           reverse_p95_mm=distances["model_to_target"]["p95_mm"],
                           solve_cpu_hours=round(cost["seconds"] / 3600.0, 3), n_elements=len(project.faces),
                           steps_solved_here=cost["steps_solved_here"], steps_restored=cost["steps_restored"],
                           head_sha256=file_sha256(heads[subject, condition])[:16], solver=cost["solver"])
            rows.append(row)
    return rows


def _within(goal: tuple[float, float], delta_qe_pp: float, delta_pe_deg: float) -> bool:
    """Whether |ΔQE| and |ΔPE| are within a goal (pp, deg)."""
    return abs(delta_qe_pp) <= goal[0] and abs(delta_pe_deg) <= goal[1]


def _alignment_gain(default: dict, rows: list[dict]) -> str:
    """The default-PPM control (no goal of its own): how much QE and PE the fit takes off the posed template."""
    fit = next((r for r in rows if r["subject"] == default["subject"] and r["condition"] == "ppm"), None)
    line = (f"{default['subject']} default_ppm (no goal: what the alignment buys): ΔQE {default['delta_qe_pp']:+.2f} pp, "
            f"ΔPE {default['delta_pe_deg']:+.2f}°")
    if fit is not None:
        line += (f"; the aligned PPM takes {default['qe_percent'] - fit['qe_percent']:.2f} pp of QE and "
                 f"{default['pe_deg'] - fit['pe_deg']:.2f}° of PE off it")
    return line


def goal_lines(rows: list[dict]) -> list[str]:
    """One line per subject and goal condition: met or missed, with the numbers."""
    lines = []
    for row in rows:
        goal = GOALS.get(row["condition"])
        if row["condition"] == "default_ppm":
            lines.append(_alignment_gain(row, rows))
        if goal is None:
            continue
        verdict = "met" if _within(goal, row["delta_qe_pp"], row["delta_pe_deg"]) else "MISSED"
        lines.append(f"{row['subject']} {row['condition']}: ΔQE {row['delta_qe_pp']:+.2f} pp (goal ±{goal[0]:g}), "
                     f"ΔPE {row['delta_pe_deg']:+.2f}° (goal ±{goal[1]:g}): {verdict}")
        if row.get("delta_qe_vs_original_pp") is not None:
            qe, pe = row["delta_qe_vs_original_pp"], row["delta_pe_vs_original_deg"]
            lines.append(f"{row['subject']} {row['condition']} vs the original head solved here: ΔQE {qe:+.2f} pp, "
                         f"ΔPE {pe:+.2f}°: {'met' if _within(goal, qe, pe) else 'MISSED'}")
    return lines


def _paper_deltas(row: dict) -> tuple[float, float] | None:
    """ΔQE (pp) and ΔPE (deg) of a row by the paper's protocol, or None where the subject has no ``original``."""
    if row.get("delta_qe_paper_pp") is None or row.get("delta_pe_paper_deg") is None:
        return None
    return row["delta_qe_paper_pp"], row["delta_pe_paper_deg"]


def paper_goal_lines(rows: list[dict]) -> list[str]:
    """The goals judged by the paper's protocol (``original`` as reference and template, S at 8 % QE on it): one
    line per subject and goal condition, and for :data:`NEARER_THAN` whether it comes nearer ``original`` than
    each of the others (|ΔQE| and |ΔPE| both smaller)."""
    lines = []
    for row in rows:
        goal, deltas = GOALS.get(row["condition"]), _paper_deltas(row)
        if goal is None or deltas is None:
            continue
        qe, pe = deltas
        lines.append(f"{row['subject']} {row['condition']}, paper's protocol: ΔQE {qe:+.2f} pp (goal ±{goal[0]:g}), "
                     f"ΔPE {pe:+.2f}° (goal ±{goal[1]:g}): {'met' if _within(goal, qe, pe) else 'MISSED'}")
        for other_name in NEARER_THAN.get(row["condition"], ()):
            other = next((r for r in rows if r["subject"] == row["subject"] and r["condition"] == other_name), None)
            other_deltas = _paper_deltas(other) if other is not None else None
            if other_deltas is None:
                continue
            nearer = abs(qe) < abs(other_deltas[0]) and abs(pe) < abs(other_deltas[1])
            lines.append(f"{row['subject']} {row['condition']} nearer original than {other_name} (ΔQE "
                         f"{other_deltas[0]:+.2f} pp, ΔPE {other_deltas[1]:+.2f}°): {'met' if nearer else 'MISSED'}")
    return lines
