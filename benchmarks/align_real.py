"""Benchmark: automatic PPM alignment on real scanned ears (leave-one-subject-out) and on synthetic scans.

For every subject under --data-root (default ../shared/data/sonicom) the left pinna crop is fitted with a
template built without that subject (taken from --templates, e.g. the workflow's results/templates, or
built here with one registration round when missing). Beside it, a generic non-rigid ICP of the same
template (trimesh.registration.nricp_amberg) shows what the PPM's low-dimensional structure costs or gains.
Synthetic scans of the PPM itself (random in-range parameters, 0.2 mm noise, holes, 2 % outliers) show
how well known parameters are recovered.

Run: .venv/bin/python benchmarks/align_real.py [--synthetic N]
Prints readable lines, then one JSON line.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import bpy  # noqa: F401  (before pymeshlab)
import numpy as np
import trimesh

from ppm.align import AlignSettings, align, prepare_target
from ppm.align.report import distance_summary, one_sided_distances_mm
from ppm.align.synthetic import synthetic_scan
from ppm.model import PinnaModel
from ppm.parameters import parameter_specs
from ppm.template import default_template_dir
from ppm.template.build import build_template_folder
from ppm.template.register import register_onto

ROOT = Path(__file__).resolve().parents[1]


def loo_template(data_root: Path, subject: str, templates: Path, cache: Path) -> Path:
    """The template folder without `subject`: from `templates` if built there, else built into `cache`."""
    for folder in (templates / f"without_{subject}", cache / f"without_{subject}"):
        if (folder / "template_left.ply").is_file():
            return folder
    print(f"  building a template without {subject} (one registration round) ...", flush=True)
    return build_template_folder(data_root, cache / f"without_{subject}", exclude=[subject],
                                 topology_dir=default_template_dir(), rounds=1)


def nricp_baseline(template: trimesh.Trimesh, target) -> tuple[dict, float]:
    """Rigid ICP then non-rigid ICP (Amberg) of the template onto the target points."""
    start = time.perf_counter()
    registered = register_onto(template, target.mesh)
    seconds = time.perf_counter() - start
    return distance_summary(one_sided_distances_mm(target, registered, template.faces)), seconds


def parameter_group(spec) -> str:
    if spec.target == "Size-Bendy":
        return f"parent_{spec.kind}"
    if spec.kind in ("location", "rotation"):
        return f"control_{spec.kind}"
    return "bendy_scale" if spec.kind == "scale" else "shape_key"


def region_medians(template_dir: Path, vertices_mm: np.ndarray, points_mm: np.ndarray,
                   distance_mm: np.ndarray) -> dict[str, float]:
    """Median scan -> PPM distance (mm) per anatomical region, the regions taken from the landmarks on the fitted
    PPM (reporting/pinna_regions.py, as the evaluation's regions.csv)."""
    from ppm.landmarks import read_landmark_file  # noqa: PLC0415
    from reporting.pinna_regions import label_points, region_table  # noqa: PLC0415

    marks = read_landmark_file(template_dir / "landmarks.yaml")
    positions = {name: vertices_mm[int(entry["vertex"])] for name, entry in marks.items()}
    return {row["region"]: round(row["median_mm"], 3)
            for row in region_table(label_points(points_mm, positions), distance_mm)}


def signed_region_medians(template_dir: Path, vertices_mm: np.ndarray, faces: np.ndarray,
                          points_mm: np.ndarray) -> dict[str, float]:
    """Median signed distance (mm) per region of every scan point from its closest point on the fitted PPM, along
    that face's outward normal: negative where the scan lies behind (inside) the fitted surface, e.g. a deeper
    concha than the fit's."""
    fitted = trimesh.Trimesh(vertices_mm, faces, process=False)
    closest, _, face = trimesh.proximity.closest_point(fitted, points_mm)
    signed = np.einsum("ij,ij->i", points_mm - closest, fitted.face_normals[face])
    return region_medians(template_dir, vertices_mm, points_mm, signed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data-root", type=Path, default=ROOT.parent / "shared" / "data" / "sonicom")
    parser.add_argument("--templates", type=Path, default=ROOT / "results" / "templates")
    parser.add_argument("--cache", type=Path, default=ROOT / "results" / "benchmarks" / "templates")
    parser.add_argument("--synthetic", type=int, default=5, help="number of synthetic scans")
    parser.add_argument("--normal-min-cosine", type=float, default=None,
                        help="ignore scan -> model pairs whose normals meet at a cosine below this (default: keep all)")
    parser.add_argument("--restarts", type=int, default=AlignSettings.restarts,
                        help=f"basin-hopping refits after the staged fit (default {AlignSettings.restarts}; 0: none)")
    parser.add_argument("--fold-weight", type=float, default=AlignSettings.fold_weight,
                        help=f"the fold barrier's weight (default {AlignSettings.fold_weight})")
    args = parser.parse_args()
    settings = AlignSettings(normal_min_cosine=args.normal_min_cosine, restarts=args.restarts,
                             fold_weight=args.fold_weight)
    print(f"alignment settings: normal_min_cosine = {args.normal_min_cosine}, restarts = {args.restarts}, "
          f"fold_weight = {args.fold_weight}")

    subjects = sorted(p.name for p in args.data_root.iterdir() if (p / "pinna_left_crop.ply").is_file())
    rows = {}
    for subject in subjects:
        template_dir = loo_template(args.data_root, subject, args.templates, args.cache)
        model = PinnaModel.from_template(template_dir)
        target = prepare_target(args.data_root / subject / "pinna_left_crop.ply")
        result = align(model, target, settings)
        distance = one_sided_distances_mm(target, result.vertices_mm, model.faces)
        ppm = distance_summary(distance)
        regions = region_medians(template_dir, result.vertices_mm, target.points_mm, distance)
        nricp, nricp_seconds = nricp_baseline(model.mesh(), target)
        rows[subject] = {"median_mm": ppm["median_mm"], "p95_mm": ppm["p95_mm"], "mean_mm": ppm["mean_mm"],
                         "share_under_1mm": ppm["share_under_1mm"], "seconds": round(result.seconds, 1),
                         "nricp_median_mm": nricp["median_mm"], "nricp_p95_mm": nricp["p95_mm"],
                         "nricp_seconds": round(nricp_seconds, 1), "region_median_mm": regions,
                         "warnings": result.warnings}
        print(f"{subject}: PPM median {ppm['median_mm']:.3f} mm, p95 {ppm['p95_mm']:.3f} mm, mean {ppm['mean_mm']:.3f} mm, "
              f"{100 * ppm['share_under_1mm']:.1f} % < 1 mm, {result.seconds:.1f} s | NRICP median "
              f"{nricp['median_mm']:.3f} mm, p95 {nricp['p95_mm']:.3f} mm, {nricp_seconds:.1f} s", flush=True)
        print(f"{subject}: PPM median per region (mm): {regions}", flush=True)
        signed = signed_region_medians(template_dir, result.vertices_mm, model.faces, target.points_mm)
        rows[subject]["region_signed_median_mm"] = signed
        print(f"{subject}: median signed distance per region (mm, < 0: the scan lies behind the fit): {signed}",
              flush=True)

    model = PinnaModel.from_template()
    rng = np.random.default_rng(2026)
    synthetic_medians, vertex_errors, surface_errors, group_errors = [], [], [], {}
    for index in range(args.synthetic):
        target, truth = synthetic_scan(model, rng)
        result = align(model, target, settings)
        distance = one_sided_distances_mm(target, result.vertices_mm, model.faces)
        truth_vertices = model.evaluate(truth)
        vertex_error = np.linalg.norm(result.vertices_mm - truth_vertices, axis=1)
        surface_error = trimesh.proximity.closest_point(trimesh.Trimesh(truth_vertices, model.faces, process=False),
                                                        result.vertices_mm)[1]
        synthetic_medians.append(float(np.median(distance)))
        vertex_errors.append(float(np.median(vertex_error)))
        surface_errors.append(float(np.median(surface_error)))
        for spec, error in zip(parameter_specs(), np.abs(result.parameters.to_vector() - truth.to_vector())):
            group_errors.setdefault(parameter_group(spec), []).append(float(error))
        print(f"synthetic {index}: scan->PPM median {np.median(distance):.3f} mm, PPM vertices to the true surface "
              f"median {np.median(surface_error):.3f} mm, PPM vertices vs their true places median "
              f"{np.median(vertex_error):.3f} mm, p95 {np.percentile(vertex_error, 95):.3f} mm, {result.seconds:.1f} s")
    groups = {name: round(float(np.median(values)), 4) for name, values in group_errors.items()}
    print("synthetic parameter errors (median |fit - truth|; mm, deg, factor, weight):", groups)

    worst = max(rows, key=lambda s: rows[s]["median_mm"])
    print(json.dumps({
        "median_mm": rows[worst]["median_mm"],
        "p95_mm": max(r["p95_mm"] for r in rows.values()),
        "seconds": max(r["seconds"] for r in rows.values()),
        "nricp_median_mm": max(r["nricp_median_mm"] for r in rows.values()),
        "nricp_seconds": max(r["nricp_seconds"] for r in rows.values()),
        "synthetic_median_mm": round(float(np.max(synthetic_medians)), 4),
        "synthetic_surface_error_median_mm": round(float(np.median(surface_errors)), 4),
        "synthetic_vertex_error_median_mm": round(float(np.median(vertex_errors)), 4),
        "synthetic_parameter_error_median": groups,
        "subjects": rows,
    }))


if __name__ == "__main__":
    main()
