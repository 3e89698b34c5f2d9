"""How much of a hard head's miss lies where its defective scan saw nothing: the personal-detail layer laid on the
``ppm_hard`` fit towards the defective scan plus the clean crop's surface over the parts that scan never saw, to be
stitched and solved like the evaluation's ``ppm_detail_hard`` head.

    .venv/bin/python studies/unseen_from_clean.py --subject P143 --out-dir DIR

Reads what the workflow makes for the ``*_hard`` conditions: the PPM fit of the fixed defective scan
(``results/<subject>/controls/ppm_hard/align/aligned_pinna.blend``) and its prepared scan
(``results/<subject>/controls/hard/target/pinna_target.ply``), with the evaluation's hard scan and the clean crop. A
clean crop face is *unseen* when none of its corners has a scan point within ``committed.SEEN_MM`` (2 mm, as
``studies/detail_unseen.py``); those faces join the prepared scan as more evidence, and the layer (shipped settings)
is laid on the PPM fit towards both. Writes ``aligned_pinna.ply`` (mm, project frame), ``aligned_pinna.blend`` and
``target.ply`` (the scan with the unseen parts) into ``--out-dir``: put the first two in place of
``results/<subject>/controls/ppm_detail_hard/align/``'s and solve (studies/results/unseen_from_clean/README.md). Prints
how far the clean crop lies from the new pinna: all of it (its skin ring past the PPM included, hence a large p95) and
over the unseen parts. Last line: JSON.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from committed import crop_seen_by_hard_scan, require_workflow_files, subject_parser

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = subject_parser(__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, required=True, help="folder for the pinna, its .blend and the scan")
    args = parser.parse_args()
    import bpy  # noqa: F401, PLC0415  (before anything that may load pymeshlab)
    import trimesh  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.detail import add_personal_detail  # noqa: PLC0415
    from ppm.mesh_io import write_mesh  # noqa: PLC0415
    from ppm.model import PinnaModel  # noqa: PLC0415

    controls = ROOT / "results" / args.subject / "controls"
    blend, target_path = controls / "ppm_hard" / "align" / "aligned_pinna.blend", controls / "hard" / "target" / "pinna_target.ply"
    require_workflow_files(blend, target_path)
    crop, seen = crop_seen_by_hard_scan(args.evaluation, args.subject)
    prepared = trimesh.load(target_path, process=False, force="mesh")
    unseen_faces = ~seen[crop.faces].any(axis=1)
    unseen_part = trimesh.Trimesh(crop.vertices, crop.faces[unseen_faces], process=False)
    unseen_part.remove_unreferenced_vertices()
    combined = trimesh.util.concatenate([prepared, unseen_part])
    args.out_dir.mkdir(parents=True, exist_ok=True)
    write_mesh(args.out_dir / "target.ply", combined.vertices, combined.faces)
    model = PinnaModel.from_blend(str(blend))
    target = prepare_target(str(args.out_dir / "target.ply"), side="left", segment=False)
    _, summary = add_personal_detail(model, target)
    model.export(str(args.out_dir / "aligned_pinna.ply"))
    model.save_blend(str(args.out_dir / "aligned_pinna.blend"))
    posed = model.evaluate()
    truth = np.abs(trimesh.proximity.ProximityQuery(trimesh.Trimesh(posed, model.faces, process=False))
                   .signed_distance(crop.vertices))
    figures = {"subject": args.subject, "unseen_crop_faces": int(unseen_faces.sum()),
               "crop_to_pinna_median_mm": round(float(np.median(truth)), 3),
               "crop_to_pinna_p95_mm": round(float(np.percentile(truth, 95)), 3),
               "unseen_crop_to_pinna_median_mm": round(float(np.median(truth[~seen])), 3),
               "fold_halvings": summary["layer"]["fold_halvings"], "out_dir": str(args.out_dir)}
    print(f"{args.subject}: {figures['unseen_crop_faces']:,} clean crop faces the scan never saw added to it; the layer's "
          f"pinna lies {figures['crop_to_pinna_median_mm']:.3f} mm (median), p95 {figures['crop_to_pinna_p95_mm']:.3f} mm "
          f"from the clean crop, {figures['unseen_crop_to_pinna_median_mm']:.3f} mm over the unseen parts")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
