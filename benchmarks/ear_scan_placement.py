"""Benchmark: how far a separate ear scan lands from its true place on the head, registered (listener.ear_scan's
register_ear_scan: any pose and unit) or placed by the head's frame (place_ear_scan: ear_scan_frame: head).

For each SONICOM subject with a both-ear head (P143 and P067 by default) and each ear, the clean crop and the hard
scan of the evaluation's recipe (the left ear: evaluation/sonicom/hard_scans/; the right ear: the same recipe on the
right crop, as benchmarks/new_listener.py makes it) are turned at random (seed 5), moved and written in cm, then
brought back onto the head's ear (listener.ears.pinna_crop of listener.dataset_heads.both_ears_head) both ways. The
error is each scan vertex's distance from its true place (mm; median and max). For the registered hard scan the
benchmark also asks whether the registration could do better: a trimmed point-to-plane measure of how well the scan
lies on the head's ear (mean Geman-McClure loss of the scan's vertices, scale 0.5 mm, pairs at the crop's cut edge
left out), at the true pose, at the registered one, and at that measure's own minimum reached from the registered pose
(``refined``: Geman-McClure reweighted point-to-plane ICP). Where a pose away from the true one scores as well or
better, the scan itself does not pin its pose down, and no registration of it can.

Run: .venv/bin/python benchmarks/ear_scan_placement.py [--subjects P143 P067]   (about 2 min)
Prints one line per scan, then one JSON line: registered_hard_median_mm (mean over the hard scans of the median
vertex error), registered_hard_max_mm, registered_clean_median_mm, placed_hard_median_mm, registered_scores_better
(share of hard scans whose registered pose scores at least as well as the true pose), refined_hard_median_mm,
refined_scores_better (the same for the polished pose).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from listener.dataset_heads import both_ears_head  # noqa: E402
from listener.ear_scan import place_ear_scan, register_ear_scan  # noqa: E402
from listener.ears import pinna_crop  # noqa: E402
from ppm.align.report import boundary_samples  # noqa: E402
from new_listener import evaluation_hard_scan  # noqa: E402
from stitching.both_ears import mirror_left_right, right_ear_scan_as_left  # noqa: E402

SONICOM = ROOT.parent / "shared" / "data" / "sonicom"
#: The Geman-McClure scale of the placement score (mm): about the hard level's noise.
SCALE_MM = 0.5


def hard_scan(subject: str, side: str) -> trimesh.Trimesh:
    """The hard scan of the subject's ``side`` ear in the dataset frame (mm), as the listener benchmark makes it."""
    recipe = evaluation_hard_scan()
    if side == "left":
        return trimesh.load(ROOT / "evaluation" / "sonicom" / "hard_scans" / f"{subject}_hard_scan.ply", process=False)
    return mirror_left_right(right_ear_scan_as_left(SONICOM / subject / "pinna_right_crop.ply", subject,
                                                    recipe["level"], recipe["seed"]))


def point_to_plane(points_mm: np.ndarray, crop: trimesh.Trimesh, edge: cKDTree
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each point's signed distance along the normal of its closest point on ``crop`` (mm), that normal, and whether
    the pair counts (its closest point lies at least 1 mm from the crop's cut edge, ``edge``: a KD-tree of it)."""
    closest, _, triangle = trimesh.proximity.closest_point(crop, points_mm)
    normal = crop.face_normals[triangle]
    return np.einsum("ij,ij->i", points_mm - closest, normal), normal, edge.query(closest)[0] >= 1.0


def placement_score(vertices_mm: np.ndarray, crop: trimesh.Trimesh) -> float:
    """Mean Geman-McClure loss of the signed point-to-plane distances of ``vertices_mm`` to ``crop`` (lower: the scan
    lies better on the ear), pairs whose closest point is within 1 mm of the crop's cut edge left out."""
    residual, _, keep = point_to_plane(vertices_mm, crop, cKDTree(boundary_samples(crop)))
    ratio = (residual[keep] / SCALE_MM) ** 2
    return float(np.mean(ratio / (1.0 + ratio)))


def refined(vertices_mm: np.ndarray, crop: trimesh.Trimesh, rounds: int = 100) -> np.ndarray:
    """``vertices_mm`` moved rigidly to a minimum of :func:`placement_score`: point-to-plane ICP onto ``crop`` with
    Geman-McClure weights (iteratively reweighted least squares, linearised rotation), the cut-edge pairs left out."""
    points = np.asarray(vertices_mm, dtype=np.float64)
    edge = cKDTree(boundary_samples(crop))
    for _ in range(rounds):
        residual, normal, keep = point_to_plane(points, crop, edge)
        weight = np.where(keep, 1.0 / (1.0 + (residual / SCALE_MM) ** 2) ** 2, 0.0)
        root = np.sqrt(weight)[:, None]
        step = np.linalg.lstsq(np.hstack([np.cross(points, normal), normal]) * root, -residual * root[:, 0],
                               rcond=None)[0]
        moved = points @ Rotation.from_rotvec(step[:3]).as_matrix().T + step[3:]
        shift = float(np.linalg.norm(moved - points, axis=1).max())
        points = moved
        if shift < 1e-4:
            break
    return points


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", nargs="*", default=["P143", "P067"])
    args = parser.parse_args()
    rotation = Rotation.random(random_state=5).as_matrix()
    shift = np.array([40.0, -70.0, 20.0])
    to_frame = np.eye(4)  # the head's frame for a head scan written as the ear scans are (turned, moved, cm)
    to_frame[:3, :3] = 10.0 * rotation.T
    to_frame[:3, 3] = -rotation.T @ shift
    rows = []
    for subject in args.subjects:
        head = both_ears_head(SONICOM / subject)
        for side in ("left", "right"):
            crop = pinna_crop(head, side)
            for kind, scan in (("clean", trimesh.load(SONICOM / subject / f"pinna_{side}_crop.ply", process=False)),
                               ("hard", hard_scan(subject, side))):
                truth = np.asarray(scan.vertices)
                given = trimesh.Trimesh((truth @ rotation.T + shift) / 10.0, scan.faces, process=False)
                registered, _ = register_ear_scan(given, crop, side)
                placed, _ = place_ear_scan(given, to_frame, "cm", crop, side)
                error = {how: np.linalg.norm(np.asarray(mesh.vertices) - truth, axis=1)
                         for how, mesh in (("registered", registered), ("placed", placed))}
                row = {"subject": subject, "side": side, "kind": kind,
                       **{f"{how}_median_mm": round(float(np.median(e)), 3) for how, e in error.items()},
                       **{f"{how}_max_mm": round(float(e.max()), 3) for how, e in error.items()},
                       "score_true": round(placement_score(truth, crop), 5),
                       "score_registered": round(placement_score(np.asarray(registered.vertices), crop), 5)}
                if kind == "hard":  # the registered pose polished to the score's own minimum
                    polished = refined(np.asarray(registered.vertices), crop)
                    row.update(refined_median_mm=round(float(np.median(np.linalg.norm(polished - truth, axis=1))), 3),
                               score_refined=round(placement_score(polished, crop), 5))
                rows.append(row)
                print(f"{subject} {side} {kind}: registered {row['registered_median_mm']:.3f} mm median, "
                      f"{row['registered_max_mm']:.3f} max from the true place; placed by the head's frame "
                      f"{row['placed_median_mm']:.3f} / {row['placed_max_mm']:.3f}; score at the true pose "
                      f"{row['score_true']:.5f}, at the registered {row['score_registered']:.5f}"
                      + (f"; polished to the score's minimum: {row['refined_median_mm']:.3f} mm median from the true "
                         f"place, score {row['score_refined']:.5f}" if kind == "hard" else ""), flush=True)
    hard = [row for row in rows if row["kind"] == "hard"]
    clean = [row for row in rows if row["kind"] == "clean"]
    print(json.dumps({
        "registered_hard_median_mm": round(float(np.mean([r["registered_median_mm"] for r in hard])), 3),
        "registered_hard_max_mm": round(float(max(r["registered_max_mm"] for r in hard)), 3),
        "registered_clean_median_mm": round(float(np.mean([r["registered_median_mm"] for r in clean])), 3),
        "placed_hard_median_mm": round(float(np.mean([r["placed_median_mm"] for r in hard])), 3),
        "registered_scores_better": round(float(np.mean([r["score_registered"] <= r["score_true"] for r in hard])), 2),
        "refined_hard_median_mm": round(float(np.mean([r["refined_median_mm"] for r in hard])), 3),
        "refined_scores_better": round(float(np.mean([r["score_refined"] <= r["score_true"] for r in hard])), 2),
        "scans": rows}))


if __name__ == "__main__":
    main()
