"""Benchmark: PPM alignment on defective scans of real ears, from the head frame and from any pose, against
free-form non-rigid ICP, both measured against the CLEAN ear (the ground truth).

For every SONICOM subject, its clean left crop is the truth. `ppm.align.defects` makes defective scans of
it at graded levels (scanner occlusion holes, coarser sampling, noise, outliers and spikes, a partial crop;
ppm/data/scan_defects.yaml). Each scan is fitted
  * by the PPM (template built without the subject), the scan in the head frame;
  * by NRICP (trimesh's Amberg, the same template, rigid ICP first) onto the same prepared scan, with the
    stiffness schedule that is best for these scans: every schedule of SCHEDULES is tried at the hardest
    level and the one with the smallest truth distance (mean of median and p95 over subjects) is used;
  * by the PPM plus its personal-detail layer (ppm.align.detail, packaged settings) drawn towards the whole scan
    (as the workflow does; --segmented-evidence: towards the segmented pinna the fit saw, as before 2026-12-06),
    joined with the scan's reconstruction's fill of its holes where the layer's hole_fill_mm asks for it
    (stitching.reconstruction.layer_evidence; e.g. --detail hole_fill_mm=2);
  * by the scan itself made watertight as a careful user would (`poisson`: MeshLab's outlier selection and
    screened Poisson reconstruction through pymeshlab, trimmed 4 mm from the scan; stitching/reconstruction.py,
    settings in stitching/data/scan_reconstruction.yaml), the baseline the layer must beat (issue 56);
  * at the hardest level, by the PPM again from --poses random poses of the same scan (uniform rotation,
    offset up to 300 mm, unit mm / cm / m, every second one mirrored into a right ear), through the
    workflow's own path (`prepare_target(..., scan_pose="any")`, a PLY file on disk).
Distance to the truth: every truth point (pinna + 3 mm skin ring of the clean crop) to the fitted surface,
and every fitted vertex whose closest truth point lies >= 1 mm from the truth's edge to the truth surface;
the two directions pooled give the median and p95 (mm). Over the region the stitch replaces (inside the rim of the
PPM fitted to the scan), both directions again, each on its own, and the truth -> surface direction split into the
parts the scan saw (a scan point within 2 mm) and those it never saw. A posed fit succeeds when it finds the unit and side,
and, mapped back into the head frame, its surface lies within 1 mm (median, both ways) of the head-frame fit
of the same scan (the vertex-to-vertex gap, which also counts vertices sliding along the surface, is printed).

Run: .venv/bin/python benchmarks/align_defects.py [--poses 4] [--subjects P039 P067 P143] [--schedule to_0.007]
     [--no-poisson] [--kinds smooth] [--levels light hard] (--levels --kinds smooth: the smooth scans alone)
(~37 min alone with every schedule tried; --schedule skips the tuning, --poses 2 halves the posed fits)
Prints readable lines, then one JSON line.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import bpy  # noqa: F401  (before pymeshlab)
import numpy as np
import trimesh

from align_real import loo_template
from ppm.align import AlignSettings, align, prepare_target
from ppm.align.any_pose import PoseUncertainError
from ppm.align.pose_by_fit import align_any_pose
from ppm.align.defects import defective_scan, kinds, levels, random_pose
from ppm.align.detail import DetailSettings, personal_detail
from ppm.align.pose import apply_similarity
from ppm.align.report import one_sided_distances_mm, reverse_distances_mm
from ppm.align.nricp import nricp_fit as fit_nricp
from ppm.align.target import Target, surface_without_outliers
from ppm.align.widen import refit_widened
from ppm.model import PinnaModel
from ppm.template.register import NRICP_STEPS
from reporting.stitched_region import region_distances, seen_by
from stitching.reconstruction import layer_evidence, poisson_surface

ROOT = Path(__file__).resolve().parents[1]
#: NRICP stiffness schedules tried (stiff to supple): ending after 1 ... 4 of NRICP_STEPS' stages, and a
#: schedule that goes on to a very supple last stage.
SCHEDULES = {f"to_{steps[-1][0]:g}": steps for steps in (NRICP_STEPS[:k] for k in range(1, 5))}
SCHEDULES["to_0.0007"] = NRICP_STEPS + ((0.0007, 0.0, 0.5, 10),)
UNITS = ("mm", "cm", "m")


def truth_distances(truth: Target, vertices_mm: np.ndarray, faces: np.ndarray) -> dict[str, float]:
    """Both directions between a fitted surface and the clean truth (mm), and the two pooled."""
    forward = one_sided_distances_mm(truth, vertices_mm, faces)
    backward, counts = reverse_distances_mm(truth, vertices_mm, boundary_margin_mm=1.0)
    pooled = np.concatenate([forward, backward[counts]])
    return {"median_mm": float(np.median(pooled)), "p95_mm": float(np.percentile(pooled, 95)),
            "truth_to_fit_median_mm": float(np.median(forward)), "truth_to_fit_p95_mm": float(np.percentile(forward, 95)),
            "fit_to_truth_median_mm": float(np.median(backward[counts])),
            "fit_to_truth_p95_mm": float(np.percentile(backward[counts], 95))}


def at_or_below(first: dict, second: dict) -> bool:
    """Whether ``first`` is at or below ``second`` in median and p95, both directions (region_distances)."""
    return all(first[f"{d}_{q}_mm"] <= second[f"{d}_{q}_mm"] + 1e-9
               for d in ("truth_to_fit", "fit_to_truth") for q in ("median", "p95"))


def nricp_fit(template: trimesh.Trimesh, scan: trimesh.Trimesh, steps) -> tuple[np.ndarray, float]:
    """Rigid ICP, then non-rigid ICP with `steps` (ppm.align.nricp): fitted vertices (mm) and seconds."""
    start = time.perf_counter()
    return fit_nricp(template, scan, steps), time.perf_counter() - start


def fit_file(model: PinnaModel, mesh: trimesh.Trimesh, folder: Path, name: str, scan_pose: str,
             settings: AlignSettings | None = None):
    """Write the scan to PLY and fit it through the workflow's path: (target in the chosen pose, result,
    seconds). With scan_pose 'any' the pose is found and, where the rigid search left alternatives, decided by
    the PPM fit (ppm.align.pose_by_fit.align_any_pose)."""
    path = folder / f"{name}.ply"
    mesh.export(path)
    start = time.perf_counter()
    target = prepare_target(path, scan_pose=scan_pose)
    if scan_pose == "any":
        result, target = align_any_pose(model, target, settings)
    else:
        result = align(model, target, settings)
    # as the workflow: fitted again on the scan around the first fit where the segmentation left part of it out
    result, target, _ = refit_widened(model, target, result, settings)
    return target, result, time.perf_counter() - start


def detail_overrides(pairs: list[str], parser: argparse.ArgumentParser) -> tuple[dict, DetailSettings]:
    """``SETTING=VALUE`` strings -> the layer's setting overrides (values parsed as YAML: 20, 2.5, true, null) and
    the packaged settings with them."""
    import yaml  # noqa: PLC0415

    overrides = {}
    for pair in pairs:
        name, equals, value = pair.partition("=")
        if not equals:
            parser.error(f"--detail {pair!r}: give SETTING=VALUE, e.g. fold_smoothing_rounds=20")
        overrides[name.strip()] = yaml.safe_load(value)
    try:
        return overrides, DetailSettings.packaged(**overrides)
    except Exception as error:  # an unknown setting names the data file and the setting
        parser.error(f"--detail: {error}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data-root", type=Path, default=ROOT.parent / "shared" / "data" / "sonicom")
    parser.add_argument("--templates", type=Path, default=ROOT / "results" / "templates")
    parser.add_argument("--cache", type=Path, default=ROOT / "results" / "benchmarks" / "templates")
    parser.add_argument("--subjects", nargs="*", default=None)
    parser.add_argument("--poses", type=int, default=4, help="random poses per subject at the hardest level")
    parser.add_argument("--seed", type=int, default=19)
    parser.add_argument("--schedule", choices=sorted(SCHEDULES), default=None,
                        help="use this NRICP schedule instead of trying all at the hardest level (faster; the full run "
                             "picked to_0.007)")
    parser.add_argument("--no-poisson", action="store_true", help="leave out the screened Poisson baseline")
    parser.add_argument("--kinds", nargs="*", default=[], choices=kinds(),
                        help="other kinds of scan to judge after the graded levels (smooth: a photogrammetry scan)")
    parser.add_argument("--levels", nargs="*", default=None, choices=levels(),
                        help="graded levels to judge (default: all; leave them out with --levels and only --kinds)")
    parser.add_argument("--segmented-evidence", action="store_true",
                        help="draw the layer towards the segmented pinna the fit saw, not the whole scan (the old way)")
    parser.add_argument("--detail", nargs="*", default=[], metavar="SETTING=VALUE",
                        help="lay the layer with these settings of ppm/data/personal_detail.yaml changed (values read "
                             "as YAML), e.g. --detail fold_smoothing_rounds=20")
    parser.add_argument("--fold-weight", type=float, default=AlignSettings.fold_weight,
                        help=f"the aligner's fold barrier weight (default {AlignSettings.fold_weight})")
    args = parser.parse_args()
    settings = AlignSettings(fold_weight=args.fold_weight)
    print(f"alignment settings: fold_weight = {args.fold_weight}")
    overrides, detail_settings = detail_overrides(args.detail, parser)
    if overrides:
        print(f"personal-detail settings changed: {overrides}")
    schedules = {args.schedule: SCHEDULES[args.schedule]} if args.schedule else SCHEDULES

    subjects = args.subjects or sorted(p.name for p in args.data_root.iterdir()
                                       if (p / "pinna_left_crop.ply").is_file())
    grades = levels()
    chosen = grades if args.levels is None else [grade for grade in grades if grade in args.levels]
    measured = chosen + list(args.kinds)  # the graded levels, then other kinds (smooth), judged alike
    if not measured:
        parser.error("nothing to judge: give --levels or --kinds")
    # NRICP's schedules are tried, the posed fits made and the headline figures taken at the hardest graded level
    # judged (the last kind where no graded level is)
    hardest = chosen[-1] if chosen else measured[-1]
    rng = np.random.default_rng(args.seed)
    rows: dict[str, dict[str, dict]] = {}
    keep: dict[str, tuple[trimesh.Trimesh, Target]] = {}  # per subject: LOO template, clean truth
    nricp_by_schedule: dict[str, list[dict]] = {name: [] for name in schedules}
    pose_results, fit_seconds, nricp_seconds, detail_seconds, poisson_seconds = [], [], [], [], []
    work = Path(tempfile.mkdtemp(prefix="align_defects_"))
    for subject in subjects:
        crop = args.data_root / subject / "pinna_left_crop.ply"
        model = PinnaModel.from_template(loo_template(args.data_root, subject, args.templates, args.cache))
        template = model.mesh()
        truth = prepare_target(crop)
        clean = trimesh.load(crop, process=False)
        rows[subject] = {}
        keep[subject] = (template, truth)
        for level in measured:
            scan = defective_scan(clean, level, rng, posed=False)
            target, result, seconds = fit_file(model, scan.mesh, work, f"{subject}_{level}", "project_frame",
                                               settings)
            ppm = truth_distances(truth, result.vertices_mm, model.faces)
            start = time.perf_counter()
            # the layer's evidence: the whole scan (outliers left to the layer's own guards), as the workflow gives
            # it, or with --segmented-evidence only the pinna cut out for the fit (the layer before 2026-12-06)
            evidence = layer_evidence(target if args.segmented_evidence else
                                      prepare_target(work / f"{subject}_{level}.ply", segment=False), detail_settings)
            layer = personal_detail(result.vertices_mm, model.faces, evidence, detail_settings)
            detail = truth_distances(truth, result.vertices_mm + layer.displacement_mm, model.faces)
            detail_seconds.append(time.perf_counter() - start)
            guide = trimesh.Trimesh(result.vertices_mm, model.faces, process=False)
            seen = seen_by(scan.mesh.vertices, truth.points_mm)
            regions = {"ppm": region_distances(truth, seen, guide, result.vertices_mm, model.faces),
                       "ppm_detail": region_distances(truth, seen, guide, result.vertices_mm + layer.displacement_mm,
                                                      model.faces)}
            if not args.no_poisson:
                start = time.perf_counter()
                reconstruction = poisson_surface(scan.mesh, source=f"{subject} {level} scan")
                poisson_seconds.append(time.perf_counter() - start)
                regions["poisson"] = region_distances(truth, seen, guide, reconstruction.surface.vertices,
                                                      reconstruction.surface.faces)
                print(f"{subject} {level}: screened Poisson (trimmed) over the stitched region: truth->surface "
                      f"{regions['poisson']['truth_to_fit_median_mm']:.3f}/{regions['poisson']['truth_to_fit_p95_mm']:.3f}"
                      f", surface->truth {regions['poisson']['fit_to_truth_median_mm']:.3f}/"
                      f"{regions['poisson']['fit_to_truth_p95_mm']:.3f} mm; layer "
                      f"{regions['ppm_detail']['truth_to_fit_median_mm']:.3f}/{regions['ppm_detail']['truth_to_fit_p95_mm']:.3f}"
                      f", {regions['ppm_detail']['fit_to_truth_median_mm']:.3f}/"
                      f"{regions['ppm_detail']['fit_to_truth_p95_mm']:.3f} mm; never seen: PPM "
                      f"{regions['ppm']['unseen_median_mm']:.3f}, layer {regions['ppm_detail']['unseen_median_mm']:.3f}, "
                      f"Poisson {regions['poisson']['unseen_median_mm']:.3f} mm (median)", flush=True)
            surface = surface_without_outliers(target)
            tried = schedules if level == hardest else {}
            for name, steps in tried.items():
                vertices, nricp_time = nricp_fit(template, surface, steps)
                nricp_by_schedule[name].append(truth_distances(truth, vertices, model.faces))
                nricp_seconds.append(nricp_time)
            rows[subject][level] = {"ppm": ppm, "ppm_detail": detail, "regions": regions, "layer": layer.summary(),
                                    "scan_points": int(len(target.points_mm)),
                                    "kept_share": round(scan.kept_share, 3), "fit_seconds": round(seconds, 1),
                                    "_surface": surface}
            print(f"{subject} {level}: scan {len(target.points_mm)} points ({100 * scan.kept_share:.0f} % of the "
                  f"area seen); PPM to truth median {ppm['median_mm']:.3f} p95 {ppm['p95_mm']:.3f} mm "
                  f"(truth->fit {ppm['truth_to_fit_median_mm']:.3f}/{ppm['truth_to_fit_p95_mm']:.3f}, fit->truth "
                  f"{ppm['fit_to_truth_median_mm']:.3f}/{ppm['fit_to_truth_p95_mm']:.3f}), {seconds:.1f} s; with the personal "
                  f"detail {detail['median_mm']:.3f} / {detail['p95_mm']:.3f} mm", flush=True)
            if level != hardest:
                continue
            for index in range(args.poses):
                unit, mirrored = UNITS[index % len(UNITS)], index % 2 == 1
                truth_to_scan = random_pose(rng, unit, mirrored)
                posed = apply_similarity(scan.mesh, truth_to_scan)
                label = f"{subject} pose {index} ({unit}{', right ear' if mirrored else ''})"
                try:
                    posed_target, posed_result, seconds = fit_file(model, posed, work, f"{subject}_pose{index}", "any",
                                                                   settings)
                except PoseUncertainError as exc:
                    print(f"{label}: refused: {exc}", flush=True)
                    pose_results.append({"subject": subject, "success": False, "refused": str(exc)})
                    continue
                fit_seconds.append(seconds)
                to_project = np.asarray(posed_target.pose["matrix"]) @ truth_to_scan
                back = trimesh.transform_points(posed_result.vertices_mm, np.linalg.inv(to_project))
                # where the posed fit's surface lies against the head-frame fit's surface (both ways); the
                # vertices themselves may also slide along the surface (overlapping bone weights)
                head_fit = trimesh.Trimesh(result.vertices_mm, model.faces, process=False)
                posed_fit = trimesh.Trimesh(back, model.faces, process=False)
                gap = float(np.median(np.concatenate([trimesh.proximity.closest_point(head_fit, back)[1],
                                                      trimesh.proximity.closest_point(posed_fit, result.vertices_mm)[1]])))
                slide = float(np.median(np.linalg.norm(back - result.vertices_mm, axis=1)))
                posed_truth = truth_distances(truth, back, model.faces)
                success = (gap < 1.0 and posed_target.pose["unit"] == unit
                           and posed_target.pose["mirrored"] == mirrored)
                pose_results.append({"subject": subject, "success": success, "gap_median_mm": round(gap, 3),
                                     "vertex_gap_median_mm": round(slide, 3),
                                     "unit": posed_target.pose["unit"], "mirrored": posed_target.pose["mirrored"],
                                     "truth_median_mm": round(posed_truth["median_mm"], 3), "seconds": round(seconds, 1)})
                print(f"{label}: found {posed_target.pose['unit']}, {'mirrored' if posed_target.pose['mirrored'] else 'left'}"
                      f", next rigid pose {posed_target.pose['runner_up_ratio']}x worse; fit vs head-frame fit: surfaces "
                      f"{gap:.3f} mm apart (median), vertices {slide:.3f} mm; to truth median {posed_truth['median_mm']:.3f} p95 {posed_truth['p95_mm']:.3f} mm,"
                      f" {seconds:.1f} s -> {'ok' if success else 'FAILED'}", flush=True)

    def badness(results: list[dict]) -> float:
        return float(np.mean([r["median_mm"] + r["p95_mm"] for r in results]))

    for name, results in nricp_by_schedule.items():
        print(f"NRICP schedule {name} at {hardest}: truth median {np.mean([r['median_mm'] for r in results]):.3f}, "
              f"p95 {np.mean([r['p95_mm'] for r in results]):.3f} mm (mean over subjects)")
    best = min(nricp_by_schedule, key=lambda name: badness(nricp_by_schedule[name]))
    print(f"NRICP: best schedule at {hardest} is {best}; used at every level")
    for subject in subjects:
        template, truth = keep[subject]
        for level in measured:
            row = rows[subject][level]
            if level == hardest:
                nricp = nricp_by_schedule[best][subjects.index(subject)]
            else:
                vertices, nricp_time = nricp_fit(template, row["_surface"], SCHEDULES[best])
                nricp_seconds.append(nricp_time)
                nricp = truth_distances(truth, vertices, template.faces)
            row["nricp"] = nricp
            del row["_surface"]
            if "poisson" in row["regions"]:
                row["detail_beats_poisson"] = at_or_below(row["regions"]["ppm_detail"], row["regions"]["poisson"])
            detail = row["ppm_detail"]
            row["detail_beats_both"] = bool(
                detail["median_mm"] <= min(row["ppm"]["median_mm"], nricp["median_mm"])
                and detail["p95_mm"] <= min(row["ppm"]["p95_mm"], nricp["p95_mm"]))
            print(f"{subject} {level}: truth median / p95 (mm): PPM {row['ppm']['median_mm']:.3f} / "
                  f"{row['ppm']['p95_mm']:.3f}, NRICP {nricp['median_mm']:.3f} / {nricp['p95_mm']:.3f}, PPM + personal "
                  f"detail {detail['median_mm']:.3f} / {detail['p95_mm']:.3f} "
                  f"({'beats both' if row['detail_beats_both'] else 'does NOT beat both'})")

    worst_ppm = max(subjects, key=lambda s: rows[s][hardest]["ppm"]["median_mm"])
    worst_nricp = max(subjects, key=lambda s: rows[s][hardest]["nricp"]["median_mm"])
    worst_detail = max(subjects, key=lambda s: rows[s][hardest]["ppm_detail"]["median_mm"])
    beats = [rows[s][lv]["detail_beats_both"] for s in subjects for lv in measured]
    successes = [r["success"] for r in pose_results]
    with_poisson = [(s, lv) for s in subjects for lv in measured if "poisson" in rows[s][lv]["regions"]]
    poisson_keys = {}
    if with_poisson:
        def region(s: str, lv: str, method: str, key: str) -> float:
            return rows[s][lv]["regions"][method][key]

        worst = max(subjects, key=lambda s: region(s, hardest, "poisson", "truth_to_fit_median_mm"))
        poisson_keys = {
            "poisson_truth_median_mm": round(region(worst, hardest, "poisson", "truth_to_fit_median_mm"), 4),
            "poisson_truth_p95_mm": round(max(region(s, hardest, "poisson", "truth_to_fit_p95_mm") for s in subjects), 4),
            "detail_region_truth_median_mm": round(max(region(s, hardest, "ppm_detail", "truth_to_fit_median_mm")
                                                       for s in subjects), 4),
            "detail_region_truth_p95_mm": round(max(region(s, hardest, "ppm_detail", "truth_to_fit_p95_mm")
                                                    for s in subjects), 4),
            "detail_beats_poisson": round(float(np.mean([rows[s][lv]["detail_beats_poisson"] for s, lv in with_poisson])), 4),
            # over the parts the scan never saw, at the hardest level, the mean over subjects of the medians
            "unseen_ppm_median_mm": round(float(np.mean([region(s, hardest, "ppm", "unseen_median_mm")
                                                         for s in subjects])), 4),
            "unseen_detail_median_mm": round(float(np.mean([region(s, hardest, "ppm_detail", "unseen_median_mm")
                                                            for s in subjects])), 4),
            "unseen_poisson_median_mm": round(float(np.mean([region(s, hardest, "poisson", "unseen_median_mm")
                                                             for s in subjects])), 4),
            "poisson_seconds_per_scan": round(float(np.mean(poisson_seconds)), 1),
        }
        for s, lv in with_poisson:
            r = rows[s][lv]["regions"]
            print(f"{s} {lv} (stitched region, median/p95 mm): truth->surface PPM "
                  f"{r['ppm']['truth_to_fit_median_mm']:.3f}/{r['ppm']['truth_to_fit_p95_mm']:.3f}, layer "
                  f"{r['ppm_detail']['truth_to_fit_median_mm']:.3f}/{r['ppm_detail']['truth_to_fit_p95_mm']:.3f}, Poisson "
                  f"{r['poisson']['truth_to_fit_median_mm']:.3f}/{r['poisson']['truth_to_fit_p95_mm']:.3f}; surface->truth "
                  f"layer {r['ppm_detail']['fit_to_truth_median_mm']:.3f}/{r['ppm_detail']['fit_to_truth_p95_mm']:.3f}, "
                  f"Poisson {r['poisson']['fit_to_truth_median_mm']:.3f}/{r['poisson']['fit_to_truth_p95_mm']:.3f}; "
                  f"seen layer {r['ppm_detail']['seen_median_mm']:.3f} vs Poisson {r['poisson']['seen_median_mm']:.3f}, "
                  f"never seen PPM {r['ppm']['unseen_median_mm']:.3f} vs Poisson {r['poisson']['unseen_median_mm']:.3f}: "
                  f"layer {'at or below' if rows[s][lv]['detail_beats_poisson'] else 'NOT at or below'} Poisson")
    print(json.dumps({
        **poisson_keys,
        "ppm_truth_median_mm": round(rows[worst_ppm][hardest]["ppm"]["median_mm"], 4),
        "ppm_truth_p95_mm": round(max(rows[s][hardest]["ppm"]["p95_mm"] for s in subjects), 4),
        "nricp_truth_median_mm": round(rows[worst_nricp][hardest]["nricp"]["median_mm"], 4),
        "nricp_truth_p95_mm": round(max(rows[s][hardest]["nricp"]["p95_mm"] for s in subjects), 4),
        "detail_truth_median_mm": round(rows[worst_detail][hardest]["ppm_detail"]["median_mm"], 4),
        "detail_truth_p95_mm": round(max(rows[s][hardest]["ppm_detail"]["p95_mm"] for s in subjects), 4),
        "detail_beats_both": round(float(np.mean(beats)), 4),
        "detail_seconds_per_fit": round(float(np.mean(detail_seconds)), 1),
        "pose_success_rate": round(float(np.mean(successes)), 4) if successes else None,
        "levels": measured, "subjects": subjects, "detail_overrides": overrides,
        "seconds_per_fit": round(float(np.mean(fit_seconds)), 1) if fit_seconds else None,
        "nricp_schedule": best, "nricp_seconds_per_fit": round(float(np.mean(nricp_seconds)), 1),
        "poses": pose_results,
        "per_subject": {s: {lv: {"ppm": {k: round(v, 4) for k, v in rows[s][lv]["ppm"].items()},
                                 "nricp": {k: round(v, 4) for k, v in rows[s][lv]["nricp"].items()},
                                 "ppm_detail": {k: round(v, 4) for k, v in rows[s][lv]["ppm_detail"].items()},
                                 "layer": rows[s][lv]["layer"], "detail_beats_both": rows[s][lv]["detail_beats_both"],
                                 "regions": {m: {k: round(v, 4) for k, v in d.items()}
                                             for m, d in rows[s][lv]["regions"].items()}}
                            for lv in measured} for s in subjects},
    }))


if __name__ == "__main__":
    main()
