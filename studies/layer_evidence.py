"""Issue 56: from the evaluation's fixed hard scan, how near the true ear do the PPM, its personal-detail layer, the
scan made watertight by screened Poisson reconstruction, and layers drawn towards that reconstruction (instead of the
raw scan) come, over the region the stitch replaces?

    .venv/bin/python studies/layer_evidence.py --subject P143 [--trim-mm 2.0]

Reads the committed hard scan's workflow outputs (results/<subject>/controls/hard/: the scan and its prepared target;
results/<subject>/controls/ppm_hard/align/aligned_pinna.ply: the PPM fitted to it) and the clean crop (the truth).
Prints, per surface, truth -> surface and surface -> truth median / p95 (mm) over the stitched region, and truth ->
surface over the parts the scan saw (a scan point within 2 mm) and never saw. Candidate layers: the packaged layer
towards the fit's segmented target (as before 2026-12-06) and towards the whole scan (the workflow's evidence now),
the packaged layer towards the reconstruction trimmed to ``--trim-mm`` of the prepared scan (a denoised surface where the scan saw the
ear), and variants of its settings (``ppm.align.detail.DetailSettings``); last, the layer towards the
reconstruction trimmed 4 mm from the whole scan, and towards the whole scan joined with the reconstruction's fill of its
holes (its faces farther than 1 or 2 mm from every scan point), each with and without the folds smoothed
(``fold_smoothing_rounds``); every candidate from the layer's settings before 2026-12-06 (``BEFORE``). Last, the
packaged layer now (the scan joined with its reconstruction's fill of its holes, ``hole_fill_mm``, folds smoothed).
Last line: JSON of every surface's figures.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))

#: The layer's settings before 2026-12-06 (the folds halved only, the scan alone as evidence): every candidate below
#: starts from them, as when it was measured; the last row is the packaged layer now.
BEFORE = {"fold_smoothing_rounds": 0, "hole_fill_mm": None}

#: Settings tried with the reconstruction as evidence (besides the packaged ones).
VARIANTS = {
    "reach 8 mm": {"reach_mm": 8.0, "max_displacement_mm": 10.0},
    "reach 8 mm, normals 60 deg": {"reach_mm": 8.0, "max_displacement_mm": 10.0, "normal_agreement_deg": 60.0},
    "facing pairs": {"facing_pairs": True},
    "facing pairs, reach 8 mm, spikes 3 mm": {"facing_pairs": True, "reach_mm": 8.0, "max_displacement_mm": 10.0,
                                              "spike_mm": 3.0},
}


#: Settings tried with the whole scan as evidence.
WHOLE_SCAN_VARIANTS = {
    "reach 8 mm": {"reach_mm": 8.0, "max_displacement_mm": 10.0},
    "normals 60 deg": {"normal_agreement_deg": 60.0},
    "facing pairs": {"facing_pairs": True},
    "folds smoothed 20 rounds before halving": {"fold_smoothing_rounds": 20},
    "folds smoothed, reach 8 mm, normals 60 deg": {"fold_smoothing_rounds": 20, "reach_mm": 8.0,
                                                   "max_displacement_mm": 10.0, "normal_agreement_deg": 60.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--trim-mm", type=float, default=2.0)
    args = parser.parse_args()
    import bpy  # noqa: F401  (before pymeshlab)
    import numpy as np
    import trimesh

    from committed import SONICOM, require_workflow_files
    from ppm.align import prepare_target
    from ppm.align.detail import DetailSettings, personal_detail
    from ppm.align.target import Target
    from reporting.stitched_region import region_distances, seen_by
    from stitching.reconstruction import layer_evidence, poisson_surface, trimmed_near
    from stitching.replace_pinna import under_pinna

    base = ROOT / "results" / args.subject / "controls"
    scan_path, target_path = base / "hard" / "scan.ply", base / "hard" / "target" / "pinna_target.ply"
    fit_path = base / "ppm_hard" / "align" / "aligned_pinna.ply"
    require_workflow_files(scan_path, target_path, fit_path)
    truth = prepare_target(SONICOM / args.subject / "pinna_left_crop.ply")
    hard = prepare_target(target_path, side="left", segment=False)
    scan = trimesh.load(scan_path, process=False, force="mesh")
    fit = trimesh.load(fit_path, process=False, force="mesh")
    vertices, faces = np.asarray(fit.vertices), np.asarray(fit.faces)
    inside = under_pinna(truth.points_mm, fit)
    seen = seen_by(scan.vertices, truth.points_mm)
    reconstruction = poisson_surface(scan, source=str(scan_path))
    figures: dict[str, dict] = {}
    parts = {"truth_to_surface": "truth_to_fit", "surface_to_truth": "fit_to_truth", "seen": "seen", "unseen": "unseen"}

    def measure(name: str, surface_vertices, surface_faces) -> None:
        distances = region_distances(truth, seen, fit, surface_vertices, surface_faces)
        figures[name] = {key: [round(distances[f"{part}_median_mm"], 3), round(distances[f"{part}_p95_mm"], 3)]
                         for key, part in parts.items()}
        print(f"{args.subject} {name:44s} " + "  ".join(f"{key} {m:.3f}/{p:.3f}"
                                                       for key, (m, p) in figures[name].items()), flush=True)

    def before(**overrides) -> DetailSettings:
        return DetailSettings.packaged(**{**BEFORE, **overrides})

    def as_target(surface: trimesh.Trimesh) -> Target:
        mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False)
        return Target(np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals), mesh, "screened Poisson")

    print(f"{args.subject}: {int(inside.sum())} truth points in the stitched region, {int(seen[inside].sum())} seen by "
          "the scan")
    measure("PPM (ppm_hard)", vertices, faces)
    measure("screened Poisson, trimmed 4 mm", reconstruction.surface.vertices, reconstruction.surface.faces)
    measure("layer towards the segmented scan (before)",
            vertices + personal_detail(vertices, faces, hard, before()).displacement_mm, faces)
    # the workflow's evidence since 2026-12-06: the whole scan, not only the pinna the segmentation cut out for the
    # fit (which left out the lobule and the skin ring: half of the hard scans' points)
    whole = prepare_target(scan_path, side="left", segment=False)
    print(f"{args.subject}: the fit's segmented target holds {len(hard.points_mm)} points, the whole scan "
          f"{len(whole.points_mm)}")
    measure("layer towards the whole scan (packaged before)",
            vertices + personal_detail(vertices, faces, whole, before()).displacement_mm, faces)
    for name, overrides in WHOLE_SCAN_VARIANTS.items():
        layer = personal_detail(vertices, faces, whole, before(**overrides))
        measure(f"layer towards the whole scan, {name}", vertices + layer.displacement_mm, faces)
    evidence = as_target(trimmed_near(reconstruction.closed, hard.points_mm, args.trim_mm))
    measure(f"layer towards Poisson ({args.trim_mm:g} mm)",
            vertices + personal_detail(vertices, faces, evidence, before()).displacement_mm, faces)
    for name, overrides in VARIANTS.items():
        layer = personal_detail(vertices, faces, evidence, before(**overrides))
        measure(f"layer towards Poisson, {name}", vertices + layer.displacement_mm, faces)
    # the reconstruction as evidence the way the workflow takes the scan now: trimmed 4 mm from the whole scan (as the
    # baseline is), with and without the folds smoothed
    trimmed_whole = trimmed_near(reconstruction.closed, whole.points_mm, 4.0)
    near_whole = as_target(trimmed_whole)
    for name, overrides in {"": {}, ", folds smoothed": {"fold_smoothing_rounds": 20}}.items():
        layer = personal_detail(vertices, faces, near_whole, before(**overrides))
        measure(f"layer towards Poisson 4 mm of the whole scan{name}", vertices + layer.displacement_mm, faces)
    # the whole scan with the reconstruction's fill of its holes: the reconstruction's faces (trimmed 4 mm from the
    # scan) farther than ``gap`` from every scan point, joined to the scan, so the raw points speak where there are
    # any and the fill only where there are none
    from scipy.spatial import cKDTree  # noqa: PLC0415

    near_scan = cKDTree(whole.points_mm)
    for gap in (1.0, 2.0):
        far = near_scan.query(trimmed_whole.triangles_center)[0] > gap
        fill = trimesh.Trimesh(trimmed_whole.vertices, trimmed_whole.faces[far], process=False)
        fill.remove_unreferenced_vertices()
        joined = as_target(trimesh.util.concatenate([whole.mesh, fill]))
        for name, overrides in {"": {}, ", folds smoothed": {"fold_smoothing_rounds": 20}}.items():
            layer = personal_detail(vertices, faces, joined, before(**overrides))
            measure(f"layer towards the scan + fill beyond {gap:g} mm{name}", vertices + layer.displacement_mm, faces)
    # the packaged layer now: the whole scan joined with its reconstruction's fill of the holes the scan surrounds
    # (stitching.reconstruction.layer_evidence), the folds smoothed
    packaged = DetailSettings.packaged()
    layer = personal_detail(vertices, faces, layer_evidence(whole, packaged), packaged)
    measure("packaged layer now (scan + hole fill, folds smoothed)", vertices + layer.displacement_mm, faces)
    # where each surface's surface -> truth tail lies: its vertices in the region by their distance to the nearest point
    # of the whole scan (share of the vertices, median and share beyond the reconstruction's p95)
    from ppm.align.report import reverse_distances_mm  # noqa: PLC0415

    bands = ((0.0, 2.0), (2.0, 4.0), (4.0, np.inf))
    tail = figures["screened Poisson, trimmed 4 mm"]["surface_to_truth"][1]
    by_band: dict[str, list] = {}
    for name, surface_vertices in (("packaged layer now", vertices + layer.displacement_mm),
                                   ("screened Poisson, trimmed 4 mm", np.asarray(reconstruction.surface.vertices))):
        back, counts = reverse_distances_mm(truth, surface_vertices, boundary_margin_mm=1.0)
        counts &= under_pinna(surface_vertices, fit)
        to_scan = near_scan.query(surface_vertices[counts])[0]
        rows = []
        for low, high in bands:
            band = (to_scan >= low) & (to_scan < high)
            rows.append([low, high if np.isfinite(high) else None, round(float(band.mean()), 3),
                         round(float(np.median(back[counts][band])), 3) if band.any() else None,
                         round(float(np.mean(back[counts][band] > tail)), 3) if band.any() else None])
            print(f"{args.subject} {name}: vertices {low:g}-{high:g} mm from the scan: {100 * rows[-1][2]:.1f} %, "
                  f"surface -> truth median {rows[-1][3]} mm, {100 * (rows[-1][4] or 0):.0f} % beyond the "
                  f"reconstruction's p95 ({tail:.2f} mm)")
        by_band[name] = rows
    print(json.dumps({"subject": args.subject, "by_scan_distance": by_band, "trim_mm": args.trim_mm, "surfaces": figures}))


if __name__ == "__main__":
    main()
