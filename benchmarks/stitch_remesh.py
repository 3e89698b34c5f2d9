"""Benchmark: every SONICOM head with its own left pinna replaced by a fitted PPM pinna, stitched and
remeshed for BEM. The PPM is fitted to the subject's left pinna scan (leave-one-subject-out template
from the workflow's results/templates when present, else the packaged default template).

Run: .venv/bin/python benchmarks/stitch_remesh.py
Last line: JSON with all_closed_manifold, the worst pinna_edge_median_mm (farthest from 1 mm),
max_triangles, seconds (stitch + remesh, slowest head) and a per-head breakdown.
"""
from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import bpy  # noqa: F401  (before pymeshlab)
import trimesh

from ppm.align import align, prepare_target
from ppm.model import PinnaModel
from stitching.pipeline import remesh_files, stitch_files

ROOT = Path(__file__).resolve().parents[1]
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"


def main() -> None:
    heads = {}
    with tempfile.TemporaryDirectory() as tmp:
        for subject in sorted(p.name for p in SONICOM.iterdir() if p.is_dir()):
            loo = ROOT / "results" / "templates" / f"without_{subject}"
            model = PinnaModel.from_template(loo if (loo / "template_left.ply").is_file() else None)
            target = prepare_target(SONICOM / subject / "pinna_left_crop.ply", side="left", margin_mm=3.0)
            fit = align(model, target)
            pinna = Path(tmp) / f"{subject}_pinna.ply"
            trimesh.Trimesh(fit.vertices_mm, model.faces, process=False).export(pinna)
            head = SONICOM / subject / "head_graded_left.ply"
            start = time.perf_counter()
            stitch = stitch_files(head, pinna, Path(tmp) / f"{subject}_stitched.ply", Path(tmp) / f"{subject}_s.json")
            report = remesh_files(Path(tmp) / f"{subject}_stitched.ply", pinna, Path(tmp) / f"{subject}_head.ply",
                                  Path(tmp) / f"{subject}_v.json")
            seconds = time.perf_counter() - start
            original = len(trimesh.load(head, process=False).faces)
            heads[subject] = {
                "template": "leave-one-out" if (loo / "template_left.ply").is_file() else "default",
                "closed_manifold": bool(report["closed"] and report["manifold"]),
                "self_intersecting_faces": report["self_intersecting_faces"],
                "sliver_faces": report["sliver_faces"], "min_angle_deg": round(report["min_angle_deg"], 2),
                "pinna_edge_median_mm": round(report["pinna_edge_mm"]["median"], 3),
                "pinna_edge_p95_mm": round(report["pinna_edge_mm"]["p95"], 3),
                "triangles": report["n_triangles"], "original_triangles": original,
                "pinna_to_head_p95_mm": round(report["pinna_to_head_mm"]["p95"], 4),
                "max_frequency_hz_pinna": round(report["max_frequency_hz_6_per_wavelength_pinna"]),
                "seam_gap_mm": round(stitch["rim_gap_mm"], 2), "seconds": round(seconds, 1)}
            h = heads[subject]
            print(f"{subject}: closed manifold {h['closed_manifold']}, {h['self_intersecting_faces']} self-intersecting, "
                  f"{h['sliver_faces']} slivers (smallest angle {h['min_angle_deg']} deg), "
                  f"pinna edges median {h['pinna_edge_median_mm']} mm (p95 {h['pinna_edge_p95_mm']}), "
                  f"{h['triangles']} triangles (original graded mesh {original}), PPM pinna -> head p95 "
                  f"{h['pinna_to_head_p95_mm']} mm, {h['seconds']} s ({h['template']} template)")
    worst = max(heads.values(), key=lambda h: abs(h["pinna_edge_median_mm"] - 1.0))
    print(json.dumps({"all_closed_manifold": all(h["closed_manifold"] and h["self_intersecting_faces"] == 0
                                                 for h in heads.values()),
                      "pinna_edge_median_mm": worst["pinna_edge_median_mm"],
                      "max_triangles": max(h["triangles"] for h in heads.values()),
                      "sliver_faces": sum(h["sliver_faces"] for h in heads.values()),
                      "min_angle_deg": min(h["min_angle_deg"] for h in heads.values()),
                      "seconds": max(h["seconds"] for h in heads.values()), "heads": heads}))


if __name__ == "__main__":
    main()
