"""Benchmark: a full HRTF run on Mesh2HRTF's example head (17,432 triangles) with the embedded solver.

Ear-canal elements found by ray from the interaural centre, a Mesh2HRTF project exported (both ears,
sagittal-plane grid at lateral -20/0/+20 deg), solved step by step with the embedded bempp-cl
solver (resumable: rerun to continue), collected to SOFA and read back with sofar's verification.

Run: .venv/bin/python benchmarks/example_head_embedded.py [--frequencies 500 1000] [--workdir DIR]
Last line: JSON with the estimated and measured seconds per step, memory estimate and SOFA check.
"""
from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import numpy as np
import sofar
import trimesh

from mesh2hrtf_io import sagittal_grid, write_project
from mesh2hrtf_io.bem import estimate_cost
from mesh2hrtf_io.embedded import solve_project_embedded
from mesh2hrtf_io.sofa_out import collect_sofa
from mesh2hrtf_io.ear_canal import ear_canal_elements

HEAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "heads" / "mesh2hrtf_example_head_5mm.ply"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frequencies", type=float, nargs="+", default=[500.0, 1000.0])
    parser.add_argument("--workdir", type=Path, default=Path("benchmarks/timings/example_head"))
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    head = trimesh.load(HEAD, process=False)
    ears = {side: ear_canal_elements(head, side, source=str(HEAD)) for side in ("left", "right")}
    grid = sagittal_grid(polar_step_deg=5.0)
    project = args.workdir / "project"
    if not (project / "parameters.json").is_file():
        write_project(project, head.vertices, head.faces, ears, [grid], args.frequencies, title="example head")
    cost = estimate_cost(len(head.vertices), len(head.faces), len(grid.points_m))
    print(f"{HEAD.name}: {len(head.vertices)} vertices, {len(head.faces)} triangles; ear elements "
          f"{ {k: v.tolist() for k, v in ears.items()} }; grid {len(grid.points_m)} points")
    print(f"estimate: {cost.seconds_per_frequency:.0f} s and {cost.memory_gb_per_frequency:.1f} GB per step, "
          f"{2 * len(args.frequencies)} steps")
    start = time.perf_counter()
    summary = solve_project_embedded(project)
    files = collect_sofa(project)
    checks = {}
    for path in files:
        sofa = sofar.read_sofa(str(path), verify=True)
        data = sofa.Data_Real + 1j * sofa.Data_Imag
        level = 20 * np.log10(np.abs(data))
        checks[path.name] = {"convention": sofa.GLOBAL_SOFAConventions, "shape": list(data.shape),
                             "level_db_min": round(float(level.min()), 2), "level_db_max": round(float(level.max()), 2)}
        print(f"{path.name}: {sofa.GLOBAL_SOFAConventions}, {data.shape}, HRTF level {level.min():.1f} to "
              f"{level.max():.1f} dB, verified by sofar")
    print(json.dumps({"n_triangles": len(head.faces), "n_vertices": len(head.vertices),
                      "frequencies_hz": args.frequencies, "estimated_seconds_per_frequency": cost.seconds_per_frequency,
                      "estimated_memory_gb": cost.memory_gb_per_frequency,
                      "seconds_per_frequency": summary["measured_seconds_per_step"],
                      "total_seconds": round(time.perf_counter() - start, 1), "sofa_verified": True, "files": checks}))


if __name__ == "__main__":
    main()
