"""Exploration for "a mesh per frequency band" (issue 40): how much NumCalc time a coarser mesh saves on the low
steps of a head whose 40 full-mesh steps are committed, and how far its pressures move.

For one head (default P143 ``original``) the exported full-mesh project is remeshed coarser for one band of
frequencies (default the steps up to 3 kHz): the faces within ``--keep-mm`` of the ear-canal source are kept as they
are (the source keeps its element area and position), the rest is remeshed by distance to the pinna (the dataset's
pinna crop) with the band's edge lengths. The band's steps are solved by NumCalc and compared with the committed
full-mesh steps of the same frequencies: magnitude difference over the 793 directions (median, p95, max dB) and
NumCalc CPU seconds. Results: benchmarks/results/band_meshes/<subject>_<head>_up_to_<Hz>_edges_<mm>.json.

This measures one band at a time to choose band limits and edge lengths; the workflow does not use band meshes yet.

Run: .venv/bin/python benchmarks/band_meshes.py [--subject P143] [--head original] [--from-hz 0] [--up-to-hz 3000]
     [--edges 3,5,8,12] [--numcalc PATH]
Last line: JSON with band_steps, elements_full, elements_band, cpu_seconds_full, cpu_seconds_band, ratio,
max_median_db, max_p95_db.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

KEPT = ROOT / "benchmarks" / "results" / "band_meshes"
DISTANCES_MM = (12.0, 30.0, 60.0, None)


def band_mesh(vertices_mm: np.ndarray, faces: np.ndarray, source_faces: np.ndarray, pinna_points_mm: np.ndarray,
              edges_mm: list[float], keep_mm: float):
    """The head remeshed with ``edges_mm`` per distance band to the pinna (12, 30, 60 mm, rest), the faces within
    ``keep_mm`` of the source's centre untouched; returns the mesh and the source's faces in it."""
    import trimesh  # noqa: PLC0415

    from stitching.remesh import _current_trimesh, _meshset_selecting, _pymeshlab, face_distance_to  # noqa: PLC0415

    pymeshlab = _pymeshlab()
    head = trimesh.Trimesh(vertices_mm, faces, process=False)
    centroids = head.triangles_center[source_faces]
    centre = centroids.mean(axis=0)
    current = head
    lower = 0.0
    for up_to, edge in zip(DISTANCES_MM, edges_mm):
        upper = np.inf if up_to is None else up_to
        distance = face_distance_to(pinna_points_mm, current)
        near_source = np.linalg.norm(current.triangles_center - centre, axis=1) < keep_mm
        selected = (distance >= lower) & (distance < upper) & ~near_source
        lower = upper
        if not selected.any():
            continue
        ms = _meshset_selecting(current, selected)
        ms.meshing_isotropic_explicit_remeshing(iterations=8, selectedonly=True, targetlen=pymeshlab.PureValue(edge),
                                                featuredeg=60.0, checksurfdist=True,
                                                maxsurfdist=pymeshlab.PureValue(max(0.05, edge / 10.0)))
        current = _current_trimesh(ms)
    # the source faces, found again by their centroids (untouched: within keep_mm of the centre)
    distance, index = __import__("scipy.spatial", fromlist=["cKDTree"]).cKDTree(current.triangles_center).query(centroids)
    if distance.max() > 1e-6:
        raise SystemExit(f"the source faces moved by {distance.max():.2e} mm in the band mesh; raise --keep-mm")
    return current, np.sort(index)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--head", default="original")
    parser.add_argument("--from-hz", type=float, default=0.0, help="the band's lowest frequency (exclusive)")
    parser.add_argument("--up-to-hz", type=float, default=3000.0)
    parser.add_argument("--edges", default="3,5,8,12", help="edge lengths (mm) within 12, 30, 60 mm of the pinna "
                        "and beyond")
    parser.add_argument("--keep-mm", type=float, default=5.0)
    parser.add_argument("--numcalc", default=None)
    args = parser.parse_args()
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io import sphere_grid, write_project  # noqa: PLC0415
    from mesh2hrtf_io.numcalc import solve_project_numcalc  # noqa: PLC0415
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415
    from mesh2hrtf_io.results import read_eval_grid_pressure  # noqa: PLC0415
    from mesh2hrtf_io.step_store import project_fingerprint, solve_seconds  # noqa: PLC0415

    full_dir = ROOT / f"results/{args.subject}/hrtf/{args.head}/project"
    if not full_dir.is_dir():
        raise SystemExit(f"{full_dir} is missing: export it first (snakemake --configfile config/paper_sonicom.yaml "
                         f"{full_dir.relative_to(ROOT)})")
    full = read_project(full_dir)
    store = ROOT / "evaluation" / "sonicom" / "steps" / args.subject / args.head / "source_1"
    fingerprint = project_fingerprint(full_dir, 1)
    steps = [i + 1 for i, f in enumerate(full.frequencies_hz) if args.from_hz < f <= args.up_to_hz]
    reference, cpu_full = [], []
    for step in steps:
        with np.load(store / f"step_{step:03d}.npz") as kept:
            if str(kept["fingerprint"]) != fingerprint:
                raise SystemExit(f"{store}: stored for another project")
            reference.append(kept["pressure"])
            cpu_full.append(solve_seconds(json.loads(str(kept["status_json"]))))
    edges = [float(e) for e in args.edges.split(",")]
    pinna = trimesh.load(ROOT.parent / "shared/data/sonicom" / args.subject / "pinna_left_crop.ply", process=False)
    start = time.perf_counter()
    mesh, source = band_mesh(full.vertices_m * 1000.0, full.faces, full.sources[0].elements,
                             np.asarray(pinna.vertices), edges, args.keep_mm)
    print(f"{args.subject} {args.head}: {len(full.faces)} elements -> {len(mesh.faces)} for the band up to "
          f"{args.from_hz:.0f}-{args.up_to_hz:.0f} Hz ({len(steps)} steps; edges {edges} mm; remeshed in {time.perf_counter() - start:.0f} s)",
          flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        project = Path(tmp) / "band"
        write_project(project, mesh.vertices, mesh.faces, {"left": source},
                      [sphere_grid(full.grids[0].name, full.grids[0].points_m)], [full.frequencies_hz[s - 1] for s in steps],
                      source_type="Left ear", speed_of_sound_m_s=full.speed_of_sound_m_s,
                      density_kg_m3=full.density_kg_m3, title="band")
        solved = read_project(project)
        area_full = float(trimesh.Trimesh(full.vertices_m * 1000, full.faces).area_faces[full.sources[0].elements].sum())
        area_band = float(mesh.area_faces[source].sum())
        result = solve_project_numcalc(project, args.numcalc)
        band = [read_eval_grid_pressure(solved.sources[0].folder, i + 1, len(full.evaluation_points_m))
                for i in range(len(steps))]
        statuses = [json.loads((solved.sources[0].folder / "be.out" / f"be.{i + 1}" / "status.json").read_text())
                    if (solved.sources[0].folder / "be.out" / f"be.{i + 1}" / "status.json").is_file() else {}
                    for i in range(len(steps))]
        shutil.rmtree(project)
    cpu_band = [solve_seconds(s) for s in statuses] if all(statuses) else list(result.get("seconds", []))
    rows = []
    for i, step in enumerate(steps):
        difference = np.abs(20 * np.log10(np.abs(band[i]) / np.abs(reference[i])))
        rows.append({"step": step, "frequency_hz": float(full.frequencies_hz[step - 1]),
                     "median_db": float(np.median(difference)), "p95_db": float(np.percentile(difference, 95)),
                     "max_db": float(difference.max()), "cpu_seconds_full": cpu_full[i],
                     "cpu_seconds_band": float(cpu_band[i]) if i < len(cpu_band) else None})
        print(f"  step {step} {rows[-1]['frequency_hz']:6.0f} Hz: |band - full| median {rows[-1]['median_db']:.3f} dB, "
              f"p95 {rows[-1]['p95_db']:.3f} dB, max {rows[-1]['max_db']:.2f} dB; NumCalc {cpu_full[i]:.0f} s full, "
              f"{rows[-1]['cpu_seconds_band'] or 0:.0f} s band")
    summary = {"subject": args.subject, "head": args.head, "from_hz": args.from_hz, "up_to_hz": args.up_to_hz, "edges_mm": edges,
               "keep_mm": args.keep_mm, "band_steps": len(steps), "elements_full": len(full.faces),
               "elements_band": len(mesh.faces), "source_area_full_mm2": round(area_full, 4),
               "source_area_band_mm2": round(area_band, 4), "cpu_seconds_full": round(sum(cpu_full), 1),
               "cpu_seconds_band": round(sum(r["cpu_seconds_band"] or 0 for r in rows), 1),
               "max_median_db": round(max(r["median_db"] for r in rows), 3),
               "max_p95_db": round(max(r["p95_db"] for r in rows), 3)}
    summary["ratio"] = round(summary["cpu_seconds_band"] / summary["cpu_seconds_full"], 3)
    KEPT.mkdir(parents=True, exist_ok=True)
    edges_name = "-".join(f"{e:g}" for e in edges)
    band_name = f"{args.from_hz:.0f}_to_{args.up_to_hz:.0f}" if args.from_hz > 0 else f"up_to_{args.up_to_hz:.0f}"
    (KEPT / f"{args.subject}_{args.head}_{band_name}_edges_{edges_name}.json").write_text(
        json.dumps({**summary, "steps": rows}, indent=2) + "\n")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
