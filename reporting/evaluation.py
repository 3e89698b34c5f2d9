"""The dataset evaluation (the paper's Figures 6 and 7 for a dataset): per subject and condition the predicted
localisation (baumgartner2014, reference as template, S calibrated on the reference), the distances between
the target scan and the condition's pinna, and the cost of solving; written as summary.csv, the solved
left-ear HRTFs, two figures, an HTML page and a README into one folder kept in the repository.

Distances are in millimetres: target -> model is the paper's one-sided Hausdorff distance (every scan point to
the pinna surface); model -> target is every model vertex to the scan surface, over the scanned region only
(:func:`ppm.align.report.reverse_distances_mm`).
"""
from __future__ import annotations

import csv
import html
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ppm.atomic import atomic_path, write_text_atomic

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


#: Columns of regions.csv: scan -> model distances per anatomical region (reporting/pinna_regions.py).
REGION_COLUMNS = ("subject", "condition", "region", "points", "median_mm", "p95_mm", "over_1mm_percent")


def region_rows(results: str | os.PathLike, subjects: list[str], conditions: dict[str, list[str]],
                positions_mm: dict[str, dict[str, np.ndarray]]) -> list[dict]:
    """One row per subject, solved condition and pinna region (:data:`REGION_COLUMNS`), the regions labelled with
    each subject's landmark positions (mm) on its aligned PPM (``positions_mm[subject]``)."""
    from .pinna_regions import subject_regions  # noqa: PLC0415

    rows = []
    for subject in subjects:
        for condition, table in subject_regions(results, subject, conditions[subject], positions_mm[subject]).items():
            rows += [{"subject": subject, "condition": condition, **row} for row in table]
    return rows


SAME_SURFACE_MM = 0.1
"""A condition whose every region lies closer than this to the scan (p95, mm) has the scanned pinna itself
(own_pinna): a tenth of the 1 mm a pinna must be captured to, and half the median of the closest PPM fit (0.2 mm);
the cut-and-stitch path moves own-pinna scan points by up to 0.06 mm (P039's tragus and seam, p95)."""


def where_lines(rows: list[dict], regions: list[dict]) -> list[str]:
    """For every condition that misses its goal (by the paper's protocol where the subject has ``original``, else
    against the dataset's HRIRs): the two pinna regions farthest from the scan, against the whole scan's median
    (the paper traced its misses to the fossa triangularis and the cymba conchae); a condition whose pinna is the
    scanned one (``SAME_SURFACE_MM``) is said to miss for another reason than its shape."""
    from .pinna_regions import worst_regions  # noqa: PLC0415

    lines = []
    for row in rows:
        goal = GOALS.get(row["condition"])
        paper = _paper_deltas(row)
        qe, pe = paper if paper is not None else (row["delta_qe_pp"], row["delta_pe_deg"])
        if goal is None or _within(goal, qe, pe):
            continue
        table = [r for r in regions if r["subject"] == row["subject"] and r["condition"] == row["condition"]]
        if not table:
            continue
        protocol = ", paper's protocol" if paper is not None else ""
        head = f"{row['subject']} {row['condition']} (ΔQE {round(qe, 3):+.2f} pp, ΔPE {round(pe, 3):+.2f}°{protocol})"
        largest_p95 = max(round(r["p95_mm"], 3) for r in table)
        if largest_p95 < SAME_SURFACE_MM:
            lines.append(f"{head}: its pinna is the scanned one (every region's p95 at most {largest_p95:.3f} mm, "
                         f"under {SAME_SURFACE_MM} mm), so its miss is not the pinna's shape.")
            continue
        worst = worst_regions(table)
        # worded from the values as the CSV files keep them (3 decimals), so the text follows from the files
        parts = [f"the {r['region']} (median {round(r['median_mm'], 3):.2f} mm, {round(r['over_1mm_percent'], 3):.0f} % "
                 f"of its {r['points']} scan points beyond 1 mm)" for r in worst]
        lines.append(f"{head}: farthest from the scan are {' and '.join(parts)}; the whole scan's median is "
                     f"{round(row['distance_median_mm'], 3):.2f} mm.")
    return lines


def region_pivot(regions: list[dict], condition: str = "ppm") -> tuple[list[dict], tuple[str, ...]]:
    """Rows: regions; columns: subjects; values: median scan -> pinna distance (mm) of `condition`."""
    subjects = list(dict.fromkeys(r["subject"] for r in regions if r["condition"] == condition))
    table: dict[str, dict] = {}
    for r in regions:
        if r["condition"] == condition:
            table.setdefault(r["region"], {"region": r["region"]})[r["subject"]] = r["median_mm"]
    return list(table.values()), ("region", *subjects)


def write_regions_csv(path: str | os.PathLike, regions: list[dict]) -> Path:
    """regions.csv (:data:`REGION_COLUMNS`), written atomically."""
    return _write_csv(path, regions, REGION_COLUMNS)


def _write_csv(path: str | os.PathLike, rows: list[dict], columns: tuple[str, ...]) -> Path:
    """`rows` as CSV with `columns` (numbers to 3 decimals, empty where a value does not apply), atomically."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({column: _fmt(row.get(column)) for column in columns})
    return write_text_atomic(path, buffer.getvalue())


def _fmt(value) -> str:
    if value is None or value == "":
        return ""
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


def write_summary_csv(path: str | os.PathLike, rows: list[dict]) -> Path:
    """summary.csv (columns :data:`COLUMNS`, empty where a value does not apply), written atomically."""
    return _write_csv(path, rows, COLUMNS)


def read_summary_csv(path: str | os.PathLike) -> list[dict]:
    """summary.csv back as rows (numbers as floats, empty cells as None)."""
    rows = []
    with open(path, newline="") as handle:
        for raw in csv.DictReader(handle):
            row = {}
            for key, value in raw.items():
                if key in ("subject", "condition", "head_sha256", "solver"):
                    row[key] = value
                else:
                    row[key] = float(value) if value != "" else None
            rows.append(row)
    return rows


def figure7(rows: list[dict], path: str | os.PathLike) -> Path:
    """QE (%) and PE (deg) per subject and condition, side by side (the paper's Figure 7): first by the paper's
    protocol (``original`` as reference and template, where the rows have its columns), then with the dataset's
    HRIRs as reference and template."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    subjects = list(dict.fromkeys(r["subject"] for r in rows))
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    protocols = [("qe_percent", "pe_deg", "template: the dataset's HRIRs")]
    if any(r.get("qe_paper_percent") is not None for r in rows):
        protocols.insert(0, ("qe_paper_percent", "pe_paper_deg", "paper's protocol; template: original (solved here)"))
    width = 0.8 / len(conditions)
    legend_columns = min(len(conditions), 5)  # wider rows ran off the figure's edges
    legend_rows = -(-len(conditions) // legend_columns)
    height_in = 0.4 + 3.2 * len(protocols) + 0.22 * legend_rows
    fig, axes = plt.subplots(len(protocols), 2, figsize=(4.0 + 1.3 * len(subjects), height_in), squeeze=False)
    for (qe_key, pe_key, title), panels in zip(protocols, axes):
        for ax, key, label in ((panels[0], qe_key, "quadrant errors (%)"), (panels[1], pe_key, "local polar RMS error (deg)")):
            for k, condition in enumerate(conditions):
                values = [next((r[key] for r in rows if r["subject"] == s and r["condition"] == condition
                                and r.get(key) is not None), np.nan) for s in subjects]
                ax.bar(np.arange(len(subjects)) + (k - (len(conditions) - 1) / 2) * width, values, width,
                       label=condition)
            ax.set_xticks(np.arange(len(subjects)), subjects)
            ax.set_ylabel(label)
            ax.grid(axis="y", alpha=0.3)
            ax.set_title(title, fontsize=8)
    # one legend under all panels: inside a panel it hides the tallest bars
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=legend_columns, fontsize=8, frameon=False)
    fig.suptitle("predicted sagittal-plane localisation (baumgartner2014, S at 8 % QE on the template)", fontsize=9)
    fig.tight_layout(rect=(0, (0.1 + 0.22 * legend_rows) / height_in, 1, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
    return Path(path)


def figure6(results: str | os.PathLike, subjects: list[str], conditions: dict[str, list[str]],
            path: str | os.PathLike) -> Path:
    """Per subject: the target scan coloured by its distance to the aligned PPM on the paper's scale (<= 1 mm
    red, ~3.5 mm green, >= 5 mm blue), the same on a 0-1.5 mm scale (where a fit that is within 1 mm nearly
    everywhere still differs), and the histogram of the distances of every condition with medians (the paper's
    Figure 6, plus the fine-scale column)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    import trimesh  # noqa: PLC0415

    from ppm.render import FINE_SCALE, PAPER_SCALE, render_distance_map  # noqa: PLC0415

    results = Path(results)
    # one colour per condition in every subject's histogram
    every = list(dict.fromkeys(c for subject in subjects for c in conditions[subject]))
    colours = {c: plt.get_cmap("tab10")(k % 10) for k, c in enumerate(every)}
    fig, axes = plt.subplots(len(subjects), 3, figsize=(16, 3.3 * len(subjects)), squeeze=False,
                             gridspec_kw={"width_ratios": [2.0, 2.0, 1.0]})
    with tempfile.TemporaryDirectory() as tmp:
        for row, subject in enumerate(subjects):
            data = {c: np.load(results / subject / "evaluation" / c / "distances.npz")
                    for c in conditions[subject]}
            target = trimesh.load(results / subject / "target" / "pinna_target.ply", process=False, force="mesh")
            forward = data["ppm"]["target_to_model"]
            # the prepared target may have dropped outliers: then its points are shown
            whole = len(target.vertices) == len(forward)
            points, faces = (target.vertices, target.faces) if whole else (data["ppm"]["target_points_mm"], None)
            for column, scale in enumerate((PAPER_SCALE, FINE_SCALE)):
                picture = Path(tmp) / f"{subject}_{column}.png"
                render_distance_map(points, faces, forward, picture, f"{subject}: scan -> PPM, {scale.label}",
                                    scale=scale)
                axes[row, column].imshow(plt.imread(picture))
                axes[row, column].axis("off")
            ax = axes[row, 2]
            bins = np.linspace(0.0, 5.0, 51)
            for condition, values in data.items():
                d = values["target_to_model"]
                ax.hist(np.clip(d, 0, 5.0), bins=bins, weights=np.full(len(d), 100.0 / len(d)), histtype="step",
                        lw=1.2, color=colours[condition], label=f"{condition}: median {np.median(d):.2f} mm")
            ax.axvline(np.median(forward), color="k", ls="--", lw=0.8)
            ax.set_xlabel("distance scan -> pinna (mm; last bin >= 5)")
            ax.set_ylabel("scan points (%)")
            ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp_png:
        fig.savefig(tmp_png, dpi=100, format="png")
    plt.close(fig)
    return Path(path)


def left_hrtf_name(subject: str, condition: str) -> str:
    """File name of a condition's solved left-ear HRTFs in an evaluation folder's ``sofa/``."""
    return f"{subject}_{condition}_left_HRTF.sofa"


def left_hrtf_files(sofa_folder: str | os.PathLike, subject: str) -> dict[str, Path]:
    """Condition -> the solved left-ear HRTF file of ``subject`` in an evaluation's ``sofa/`` folder."""
    tail = left_hrtf_name("", "")[1:]  # "_left_HRTF.sofa"
    return {path.name[len(subject) + 1:-len(tail)]: path
            for path in sorted(Path(sofa_folder).glob(left_hrtf_name(subject, "*")))}


def copy_sofa(hrtfs: dict[tuple[str, str], str], folder: str | os.PathLike) -> list[Path]:
    """The solved left-ear HRTFs (SimpleFreeFieldHRTF) as ``<subject>_<condition>_left_HRTF.sofa``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for (subject, condition), source in sorted(hrtfs.items()):
        target = folder / left_hrtf_name(subject, condition)
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
        written.append(target)
    return written


def copy_hard_scans(scans: dict[str, str], folder: str | os.PathLike) -> list[Path]:
    """The fixed defective scan each subject's *_hard conditions started from, as ``<subject>_hard_scan.ply`` (mm,
    head frame): kept with the results, so that the conditions can be judged and redone from the same scan."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for subject, source in sorted(scans.items()):
        target = folder / f"{subject}_hard_scan.ply"
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
        written.append(target)
    lines = ["# The fixed defective scans of the *_hard conditions", "",
             "Each subject's clean left crop with the defects of config `evaluation.hard_scan` (ppm/align/defects.py; "
             "mm, head frame), drawn once with the subject's own seed: the scan the conditions ppm_hard, "
             "ppm_detail_hard and nricp_hard were fitted to. Their distances are measured against the clean crop.", ""]
    lines += [f"- `{path.name}`" for path in written] or ["No *_hard condition in this evaluation."]
    written.append(write_text_atomic(folder / "README.md", "\n".join(lines) + "\n"))
    return written


def _table_html(rows: list[dict], columns: tuple[str, ...]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(r.get(c)))}</td>" for c in columns) + "</tr>"
                   for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _table_markdown(rows: list[dict], columns: tuple[str, ...]) -> str:
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_fmt(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


SHORT_COLUMNS = ("subject", "condition", "qe_percent", "pe_deg", "delta_qe_pp", "delta_pe_deg", "distance_median_mm",
                 "distance_p95_mm", "reverse_median_mm", "solve_cpu_hours")
#: The README's table by the paper's protocol (the reference row: the dataset's HRIRs heard with original's template).
PAPER_SHORT_COLUMNS = ("subject", "condition", "qe_paper_percent", "pe_paper_deg", "delta_qe_paper_pp",
                       "delta_pe_paper_deg", "distance_median_mm", "distance_p95_mm")

PAPER_PROTOCOL_TEXT = ("Per subject the unchanged head solved here (original) is the reference and the listener's "
                       "template, S is calibrated so that it reaches 8 % quadrant errors, and every condition's left "
                       "ear is predicted with them; the row reference is the dataset's own HRIRs heard with that "
                       "template.")


def _labels(rows: list[dict]) -> dict[str, str]:
    """:data:`CONDITION_LABELS` of the conditions the rows hold (all of them for rows that name none)."""
    present = {r.get("condition") for r in rows}
    return {c: t for c, t in CONDITION_LABELS.items() if c in present} or dict(CONDITION_LABELS)


def _paper_rows(rows: list[dict]) -> list[dict]:
    return [r for r in rows if r.get("qe_paper_percent") is not None]


def _regions_html(rows: list[dict], regions: list[dict] | None) -> list[str]:
    if not regions:
        return []
    pivot, columns = region_pivot(regions)
    return ["<h2>Where the geometry differs</h2>",
            "<ul>" + "".join(f"<li>{html.escape(line)}</li>" for line in where_lines(rows, regions)) + "</ul>",
            "<p>Median scan &rarr; PPM distance (mm) per region (each scan point in the region of its nearest "
            "landmark on the aligned PPM):</p>", _table_html(pivot, columns),
            "<details><summary>Every condition and region</summary>", _table_html(regions, REGION_COLUMNS),
            "</details>"]


def flat_settings(mapping: dict, prefix: str = "") -> list[tuple[str, object]]:
    """A nested config mapping as (dotted key, value) pairs, e.g. [("hrtf.step_store", "/x/steps")]."""
    pairs = []
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        pairs.extend(flat_settings(value, f"{name}.") if isinstance(value, dict) else [(name, value)])
    return pairs


def _outside_note(outside_settings: list[str] | None) -> str:
    """What configfiles from outside the repository set (a clone lacks them), one sentence; empty if none."""
    if not outside_settings:
        return ""
    return ("Also given, from outside the repository (a clone has the repository's values instead): "
            + "; ".join(f"`{entry}`" for entry in outside_settings) + ".")


def not_solved_lines(not_solved: dict[str, dict[str, str]]) -> list[str]:
    """One line per condition the pipeline could not build for a subject (config evaluation.not_solved), with its
    reason: a failure is a result, so the report says it instead of leaving the row out silently."""
    return [f"{subject} `{condition}`: {reason}" for subject, failed in sorted(not_solved.items())
            for condition, reason in failed.items()]


def write_html(path: str | os.PathLike, rows: list[dict], figure6_path: Path, figure7_path: Path,
               frequency_note: str, configfiles: list[str], regions: list[dict] | None = None,
               outside_settings: list[str] | None = None, not_solved: list[str] | None = None) -> Path:
    """The evaluation's self-contained HTML page (figures embedded); ``not_solved``: lines of
    :func:`not_solved_lines`."""
    from .subject import STYLE, _image  # noqa: PLC0415

    goals = goal_lines(rows)
    paper_rows = _paper_rows(rows)
    paper = (["<h2>By the paper's protocol</h2>", f"<p>{html.escape(PAPER_PROTOCOL_TEXT)}</p>",
              "<ul>" + "".join(f"<li>{html.escape(g)}</li>" for g in paper_goal_lines(rows)) + "</ul>",
              _table_html(paper_rows, PAPER_SHORT_COLUMNS)] if paper_rows else [])
    parts = [f"<html><head><meta charset='utf-8'><title>PPM evaluation</title><style>{STYLE}</style></head><body>",
             "<h1>PPM evaluation: HRTFs of heads with the aligned PPM pinna vs the reference</h1>",
             "<p>Per subject the left ear of each condition's head was solved (NumCalc, " + html.escape(frequency_note)
             + ") on the reference SOFA's directions; the right ear is the reference's. baumgartner2014 with the "
             "reference as template; S calibrated so that the reference reaches 8 % quadrant errors.</p>",
             "<ul>" + "".join(f"<li><b>{html.escape(c)}</b>: {html.escape(t)}</li>" for c, t in _labels(rows).items())
             + "</ul>",
             *paper,
             "<h2>Goals against the dataset's HRIRs</h2><ul>" + "".join(f"<li>{html.escape(g)}</li>" for g in goals)
             + "</ul>",
             "<h2>Figure 7: predicted localisation</h2>", _image(figure7_path),
             "<h2>Figure 6: scan to pinna distances (the paper's scale; the same on 0-1.5 mm)</h2>", _image(figure6_path),
             *_regions_html(rows, regions),
             "<h2>Summary</h2>", _table_html(rows, COLUMNS),
             *(["<h2>Not solved</h2><ul>" + "".join(f"<li>{html.escape(line.replace('`', ''))}</li>"
                                                   for line in not_solved) + "</ul>"] if not_solved else []),
             f"<p>Configuration: {html.escape(' '.join(configfiles) or 'config/config.yaml')}. "
             f"{html.escape(_outside_note(outside_settings))}</p></body></html>"]
    return write_text_atomic(path, "\n".join(parts) + "\n")


def write_readme(path: str | os.PathLike, rows: list[dict], frequency_note: str, configfiles: list[str],
                 wall_clock_hours: float, regions: list[dict] | None = None,
                 outside_settings: list[str] | None = None, not_solved: list[str] | None = None) -> Path:
    """The evaluation folder's README: what was run, by which command, at what cost, and the numbers (and the
    conditions that could not be built, ``not_solved``: lines of :func:`not_solved_lines`)."""
    command = "bash scripts/run.sh" + "".join(f" --configfile {c}" for c in configfiles)
    cpu = sum(r.get("solve_cpu_hours") or 0.0 for r in rows)
    outside = _outside_note(outside_settings)
    outside = f"{outside}\n" if outside else ""
    text = f"""# Evaluation: PPM heads vs reference HRTFs

Made by `{command}` (Snakemake; rules/evaluation.smk). Every number below is in `summary.csv`.
{outside}
- Conditions: {'; '.join(f'`{c}` = {t}' for c, t in _labels(rows).items())}.
- Solved: the left ear of each condition's head (NumCalc, {frequency_note}) on the reference SOFA's directions;
  the right ear is the reference's (rebuilt at the same frequencies). S is calibrated per subject so that the
  reference reaches 8 % quadrant errors; every condition is predicted with that S and the reference as template.
- Distances (mm): `distance_*` every scan point to the condition's pinna (the paper's one-sided Hausdorff
  distance); `reverse_*` every pinna vertex over the scanned region to the scan.
- Cost: {cpu:.2f} CPU hours of NumCalc (from the solver statuses kept with every step in `steps/`);
  {wall_clock_hours:.2f} h wall-clock of the jobs of the run that wrote this folder (Snakemake benchmark files;
  restored steps take seconds).
- `steps/` keeps every solved step with the SHA-256 of its project, and every head the pipeline built (`head.ply`):
  a fresh clone solves those very heads and restores the steps instead of solving (`head_sha256` in the summary).
  Beside each PPM head, `fit_landmarks.json` keeps the landmarks of its fit that label the scan's regions.

{_paper_markdown(rows)}## Goals against the dataset's HRIRs

{chr(10).join(f'- {g}' for g in goal_lines(rows))}

## Results

{_table_markdown(rows, SHORT_COLUMNS)}
{_not_solved_markdown(not_solved)}{_regions_markdown(rows, regions)}
Files: `summary.csv`, `regions.csv`, `report.html`, `figure6_distances.png`, `figure7_qe_pe.png`,
`sofa/<subject>_<condition>_left_HRTF.sofa` (the solved left ear, SimpleFreeFieldHRTF).
"""
    return write_text_atomic(path, text)


def _not_solved_markdown(not_solved: list[str] | None) -> str:
    if not not_solved:
        return ""
    lines = "\n".join(f"- {line}" for line in not_solved)
    return f"""
Not solved (config `evaluation.not_solved`): the pipeline could not build these heads.

{lines}
"""


def _paper_markdown(rows: list[dict]) -> str:
    paper_rows = _paper_rows(rows)
    if not paper_rows:
        return ""
    lines = "\n".join(f"- {g}" for g in paper_goal_lines(rows))
    return f"""## By the paper's protocol

{PAPER_PROTOCOL_TEXT}

{lines}

{_table_markdown(paper_rows, PAPER_SHORT_COLUMNS)}

"""


def _regions_markdown(rows: list[dict], regions: list[dict] | None) -> str:
    if not regions:
        return ""
    pivot, columns = region_pivot(regions)
    lines = "\n".join(f"- {line}" for line in where_lines(rows, regions)) or "- every goal met"
    return f"""
## Where the geometry differs

Each scan point is put in the region of its nearest landmark on the subject's aligned PPM
(`ppm/data/landmark_regions.yaml`; the landmarks kept with the PPM head, `steps/<subject>/ppm/fit_landmarks.json`);
`regions.csv` has every condition and region.

{lines}

Median scan -> PPM distance (mm) per region:

{_table_markdown(pivot, columns)}
"""
