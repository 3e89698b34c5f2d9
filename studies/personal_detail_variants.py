"""What each part of the personal-detail layer buys: the layer with one setting changed at a time, on one subject's
PPM fits of its clean crop and of one defective scan per level, against the clean truth.

    .venv/bin/python studies/personal_detail_variants.py [--subject P143] [--seed 19] [--variants NAME ...]

The PPM is fitted (template built without the subject, results/templates/without_<subject>) to the clean crop and
to one draw of each level of ppm/data/scan_defects.yaml (in the head frame); NRICP (ppm.align.nricp) is fitted to
the same scans. Each variant of ppm/data/personal_detail.yaml is then laid on the same fits. Distances are those of
benchmarks/align_defects.py (truth -> fit and fit -> truth pooled; median / p95, mm). About 10 minutes on one core.

Last line (JSON): per scan, the PPM's, NRICP's and every variant's median_mm and p95_mm.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: Variants: one setting of ppm/data/personal_detail.yaml changed from the shipped one.
VARIANTS = {
    "shipped": {},
    "pairs near the scan's edges all dropped": {"over_surface_deg": 0.0},
    "no edge test at all": {"edge_margin_mm": 0.0},
    "reach 2.5 mm": {"reach_mm": 2.5},
    "PPM -> scan pairs only": {"reverse_weight": 0.0},
    "one stiffness (0.5 mm^2)": {"stiffness_mm2": [0.5], "iterations_per_stiffness": 8},
    "pairs with facing surfaces only": {"facing_pairs": True},
    "roughness guard 10 deg": {"roughness_limit_deg": 10.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--seed", type=int, default=19)
    parser.add_argument("--variants", nargs="+", choices=sorted(VARIANTS), default=list(VARIANTS),
                        help="lay only these variants (default: all)")
    parser.add_argument("--data-root", type=Path, default=ROOT.parent / "shared" / "data" / "sonicom")
    args = parser.parse_args()
    import bpy  # noqa: F401,PLC0415  (before pymeshlab)
    import tempfile  # noqa: PLC0415

    import numpy as np  # noqa: PLC0415
    import trimesh  # noqa: PLC0415

    from align_defects import fit_file, truth_distances  # noqa: PLC0415
    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.defects import defective_scan, levels  # noqa: PLC0415
    from ppm.align.detail import DetailSettings, personal_detail  # noqa: PLC0415
    from ppm.align.nricp import nricp_fit  # noqa: PLC0415
    from ppm.align.target import surface_without_outliers  # noqa: PLC0415
    from ppm.model import PinnaModel  # noqa: PLC0415

    crop = args.data_root / args.subject / "pinna_left_crop.ply"
    model = PinnaModel.from_template(ROOT / "results" / "templates" / f"without_{args.subject}")
    template = model.mesh()
    truth = prepare_target(crop)
    clean = trimesh.load(crop, process=False)
    rng = np.random.default_rng(args.seed)
    work = Path(tempfile.mkdtemp(prefix="detail_variants_"))
    figures: dict[str, dict] = {}
    variants = {name: VARIANTS[name] for name in args.variants}
    names = list(variants)
    print(f"{'scan':8} {'PPM':>13} {'NRICP':>13} " + " ".join(f"{n[:22]:>22}" for n in names))
    for level in ["clean", *levels()]:
        mesh = clean if level == "clean" else defective_scan(clean, level, rng, posed=False).mesh
        target, result, _ = fit_file(model, mesh, work, f"{args.subject}_{level}", "project_frame")
        row = {"ppm": truth_distances(truth, result.vertices_mm, model.faces),
               "nricp": truth_distances(truth, nricp_fit(template, surface_without_outliers(target)), model.faces)}
        for name, overrides in variants.items():
            layer = personal_detail(result.vertices_mm, model.faces, target, DetailSettings.packaged(**overrides))
            row[name] = truth_distances(truth, result.vertices_mm + layer.displacement_mm, model.faces)
        figures[level] = {key: {"median_mm": round(value["median_mm"], 4), "p95_mm": round(value["p95_mm"], 4)}
                          for key, value in row.items()}
        cells = [f"{row[k]['median_mm']:.3f}/{row[k]['p95_mm']:.3f}" for k in ("ppm", "nricp", *names)]
        print(f"{level:8} {cells[0]:>13} {cells[1]:>13} " + " ".join(f"{c:>22}" for c in cells[2:]), flush=True)
    print(json.dumps({"subject": args.subject, "seed": args.seed, "variants": variants, "scans": figures}))


if __name__ == "__main__":
    main()
