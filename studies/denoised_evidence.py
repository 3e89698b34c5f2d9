"""Issues 54 and 56: would the personal-detail layer come nearer the true ear on the parts a hard scan saw if its
evidence were denoised first? The placed hard listener's two ears (results/listeners/P143_hard_placed/: the PPM fits
and the prepared ear scans, made by benchmarks/new_listener.py --hard --placed), each scan's points projected onto a
robust moving-least-squares surface of their neighbours, then the packaged layer (scan + hole fill, folds smoothed)
laid with them as evidence instead of the raw points.

The projection (:func:`mls_projected`): per scan point, the neighbours within ``radius`` (mm) whose normals lie within
60 deg of its own (not the far face of the flap), a quadric height field over its tangent plane fitted by weighted
least squares (Gaussian weights, sigma = radius / 2) with Tukey biweights on the residuals (c = 2.5 x 0.5 mm, the hard
level's noise), three rounds; the point moves along its normal onto the fit. pymeshlab's own MLS projections (APSS,
RIMLS) end in a segmentation fault on these scans in the pinned build, hence the few lines here.

Measured like studies/seen_unseen_error.py: the layered pinna's faces split into those the hard scan saw and those it
did not, each face centre to the head as scanned (area-weighted median / p95, mm); and the scan points themselves to
the head as scanned, raw and projected.

Run: .venv/bin/python studies/denoised_evidence.py [--subject P143]
Last line: JSON {side: {"points": {variant: [median, p95]}, "layer": {variant: split figures}}}.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))

#: Neighbourhood radii tried (mm): the hard scans are sampled at 2 mm.
RADII_MM = (3.5, 5.0)
#: The hard level's noise (mm, ppm/data/scan_defects.yaml): the scale of the robust weights.
NOISE_MM = 0.5


def mls_projected(points: np.ndarray, normals: np.ndarray, radius: float, rounds: int = 3) -> np.ndarray:
    """``points`` (mm) each moved along its normal onto a robust weighted quadric fitted to its neighbours within
    ``radius`` (mm) that face its way; points with fewer than 8 such neighbours stay."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    unit = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    projected = points.copy()
    for i, neighbours in enumerate(cKDTree(points).query_ball_point(points, radius)):
        neighbours = np.asarray(neighbours)
        normal = unit[i]
        neighbours = neighbours[unit[neighbours] @ normal > np.cos(np.radians(60.0))]
        if len(neighbours) < 8:
            continue
        helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        first = np.cross(normal, helper)
        first /= np.linalg.norm(first)
        second = np.cross(normal, first)
        offsets = points[neighbours] - points[i]
        u, v, height = offsets @ first, offsets @ second, offsets @ normal
        design = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], axis=1)
        spatial = np.exp(-(u * u + v * v) / (0.5 * radius) ** 2)
        robust = np.ones_like(spatial)
        for _ in range(rounds):
            root = np.sqrt(spatial * robust)
            coefficients = np.linalg.lstsq(design * root[:, None], height * root, rcond=None)[0]
            scaled = (height - design @ coefficients) / (2.5 * NOISE_MM)
            robust = np.where(np.abs(scaled) < 1.0, (1.0 - scaled * scaled) ** 2, 0.0)
        projected[i] = points[i] + coefficients[0] * normal
    return projected


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    args = parser.parse_args()
    import bpy  # noqa: F401, PLC0415  (before pymeshlab)
    import trimesh  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.detail import DetailSettings, personal_detail  # noqa: PLC0415
    from ppm.align.target import Target  # noqa: PLC0415
    from seen_unseen_error import MIRROR, STORE, split_errors  # noqa: PLC0415
    from stitching.reconstruction import layer_evidence  # noqa: PLC0415

    base = ROOT / "results" / "listeners" / f"{args.subject}_hard_placed"
    if not base.is_dir():
        raise SystemExit(f"{base} is missing: run benchmarks/new_listener.py --hard --placed first")
    scanned_head = trimesh.load(STORE / f"{args.subject}_new" / "scanned" / "head.ply", process=False, force="mesh")
    settings = DetailSettings.packaged()
    result: dict = {}
    for side in ("left", "right"):
        scan_path = base / "prepared" / f"ear_scan_{side}.ply"
        fit = trimesh.load(base / "align" / side / "aligned_pinna.ply", process=False, force="mesh")
        vertices, faces = np.asarray(fit.vertices), np.asarray(fit.faces)
        scan = prepare_target(scan_path, side=side, segment=False)  # the layer's evidence, as the workflow takes it
        raw = np.asarray(scan.mesh.vertices)
        in_head = MIRROR if side == "right" else np.eye(3)  # the fits' left-ear frame back to the head's
        normals = np.asarray(scan.mesh.vertex_normals)
        variants = {"raw scan": raw, **{f"projected, {r:g} mm": mls_projected(raw, normals, r) for r in RADII_MM}}
        result[side] = {"points": {}, "layer": {}}
        for name, points in variants.items():
            distance = trimesh.proximity.closest_point(scanned_head, points @ in_head)[1]
            result[side]["points"][name] = [round(float(np.median(distance)), 3),
                                            round(float(np.percentile(distance, 95)), 3)]
            if points is raw:  # the workflow's own evidence (its outliers removed from the points), as the pinna was laid
                evidence = scan
            else:
                mesh = trimesh.Trimesh(points, scan.mesh.faces, process=False)
                evidence = Target(points, np.asarray(mesh.vertex_normals), mesh, f"{scan_path} ({name})")
            layer = personal_detail(vertices, faces, layer_evidence(evidence, settings), settings)
            layered = ROOT / "results" / "studies" / "denoised_evidence" / f"{side}_{name.replace(' ', '_')}.ply"
            layered.parent.mkdir(parents=True, exist_ok=True)
            trimesh.Trimesh(vertices + layer.displacement_mm, faces, process=False).export(layered)
            rows = split_errors(layered, scan_path, scanned_head, side)
            result[side]["layer"][name] = rows
            print(f"{args.subject} {side:5s} {name:18s}: scan points to the head as scanned "
                  f"{result[side]['points'][name][0]:.3f} / {result[side]['points'][name][1]:.3f} mm; layered pinna "
                  f"seen {rows['seen']['median_mm']:.3f} / {rows['seen']['p95_mm']:.3f}, unseen "
                  f"{rows['unseen']['median_mm']:.3f} / {rows['unseen']['p95_mm']:.3f} mm", flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
