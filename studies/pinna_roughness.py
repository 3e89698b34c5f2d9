"""How rough each solved head's pinna is: the angles between the normals of neighbouring faces over the pinna.

    .venv/bin/python studies/pinna_roughness.py [--subject P143] [--evaluation evaluation/sonicom]

For the unchanged head (the dataset's ``head_graded_left.ply``) and every kept head of the subject
(``<evaluation>/steps/<subject>/<condition>/head.ply``, the ones solved), the neighbour pairs whose two faces both lie
within 2 mm of the clean scan target (``results/<subject>/target/pinna_target.ply``): the share creased beyond 30 and
60 degrees, the count beyond 90, and the 99th percentile and maximum angle. A layer that follows a noisy scan's noise
shows here as a rough pinna (the personal-detail layer's ``roughness_limit_deg`` guards against it). Last line: JSON.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from committed import SONICOM, require_workflow_files, subject_arguments

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
NEAR_MM = 2.0


def main() -> None:
    args = subject_arguments(__doc__.splitlines()[0])
    import trimesh  # noqa: PLC0415
    from scipy.spatial import cKDTree  # noqa: PLC0415

    target_path = ROOT / "results" / args.subject / "target" / "pinna_target.ply"
    require_workflow_files(target_path)
    tree = cKDTree(trimesh.load(target_path, process=False, force="mesh").vertices)
    heads = {"original": SONICOM / args.subject / "head_graded_left.ply"}
    heads |= {path.parent.name: path for path in sorted((args.evaluation / "steps" / args.subject).glob("*/head.ply"))}
    figures = {}
    for condition, path in heads.items():
        mesh = trimesh.load(path, process=False, force="mesh")
        near = tree.query(mesh.triangles_center)[0] < NEAR_MM
        pairs = near[mesh.face_adjacency[:, 0]] & near[mesh.face_adjacency[:, 1]]
        angles = np.degrees(mesh.face_adjacency_angles[pairs])
        figures[condition] = {"pairs": int(pairs.sum()), "over_30deg_percent": round(100.0 * float(np.mean(angles > 30)), 2),
                              "over_60deg_percent": round(100.0 * float(np.mean(angles > 60)), 3),
                              "over_90deg": int(np.sum(angles > 90)), "p99_deg": round(float(np.percentile(angles, 99)), 1),
                              "max_deg": round(float(angles.max()), 1)}
        f = figures[condition]
        print(f"{args.subject} {condition:16s} {f['pairs']:6d} pairs: >30 deg {f['over_30deg_percent']:5.2f} %, "
              f">60 deg {f['over_60deg_percent']:6.3f} %, >90 deg {f['over_90deg']:3d}, p99 {f['p99_deg']:5.1f}, "
              f"max {f['max_deg']:5.1f} deg")
    print(json.dumps({"subject": args.subject, "near_mm": NEAR_MM, "heads": figures}))


if __name__ == "__main__":
    main()
