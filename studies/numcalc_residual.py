"""How far a NumCalc step stopped by its iteration limit lies from the converged one, by where CGS stopped.

    .venv/bin/python studies/numcalc_residual.py [--numcalc PATH] [--subject P143] [--faces 6000]
        [--frequency 8000] [--fractions 0.3 0.5 0.6 0.7 0.8 0.9]

NumCalc 1.2.4's CGS solver iterates until the relative residual falls under 1e-9 and otherwise stops at
``-nitermax`` and warns; the runner (``mesh2hrtf_io.numcalc``) keeps a step stopped at or below
``ACCEPTED_RESIDUAL`` instead of solving it again with twice the iterations. This solves one step of a real
scanned head (the dataset's graded left-ear head, decimated to ``--faces`` triangles so that one solve takes
seconds; source on the left canal floor as in the pipeline; 162 points on a 1.2 m sphere) once to convergence and
once per iteration limit (``--fractions`` of the iterations convergence took), and prints, per limit, where CGS stopped (iterations, relative residual)
and how far the far-field levels are from the converged solve (dB, largest and 95th percentile over the points).

Last line (JSON): ``runs`` (``max_iterations``, ``iterations``, ``relative_residual``, ``max_abs_db``,
``p95_abs_db``), ``converged_iterations``, ``max_abs_db_at_accepted_residual`` (the largest level error of any run
stopped at or below ``ACCEPTED_RESIDUAL``), ``seconds``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mesh2hrtf_io import sphere_grid, write_project  # noqa: E402
from mesh2hrtf_io.numcalc import ACCEPTED_RESIDUAL, find_numcalc, last_residual  # noqa: E402
from mesh2hrtf_io.results import read_eval_grid_pressure  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "sonicom"
GRID_POINTS = 162  # icosphere, 2 subdivisions: about every 17 degrees


def decimated_head(path: Path, faces: int):
    """The head (mm) decimated to about ``faces`` triangles, watertight (pymeshlab's quadric edge collapse)."""
    import pymeshlab  # noqa: PLC0415
    import trimesh  # noqa: PLC0415

    meshes = pymeshlab.MeshSet()
    meshes.load_new_mesh(str(path))
    meshes.meshing_decimation_quadric_edge_collapse(targetfacenum=faces, preservenormal=True, preservetopology=True,
                                                    qualitythr=0.5, planarquadric=True)
    mesh = meshes.current_mesh()
    head = trimesh.Trimesh(mesh.vertex_matrix(), mesh.face_matrix(), process=True)
    if not head.is_watertight:
        sys.exit(f"{path}: the decimated head is not watertight; try another --faces")
    return head


def solve(numcalc: Path, source: Path, max_iterations: int, nodes: int) -> tuple[np.ndarray, tuple[int, float], float]:
    """One NumCalc run of step 1 with an iteration limit: (pressures, (iterations, relative residual), seconds)."""
    shutil.rmtree(source / "be.out", ignore_errors=True)
    start = time.perf_counter()
    result = subprocess.run([str(numcalc), "-istart", "1", "-iend", "1", "-nitermax", str(max_iterations)],
                            cwd=source, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - start
    stopped = last_residual(result.stdout)
    if stopped is None:
        sys.exit(f"{source}: NumCalc printed no CGS residual (stdout ends: {result.stdout[-300:]!r})")
    pressure = read_eval_grid_pressure(source, 1, nodes)
    return pressure, stopped, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--numcalc", default=None)
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--faces", type=int, default=6000)
    parser.add_argument("--frequency", type=float, default=8000.0, help="Hz")
    parser.add_argument("--fractions", type=float, nargs="+", default=[0.3, 0.5, 0.6, 0.7, 0.8, 0.9],
                        help="iteration limits as fractions of the iterations the converged solve took")
    args = parser.parse_args()
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io.ear_canal import ear_canal_elements  # noqa: PLC0415

    started = time.perf_counter()
    numcalc = find_numcalc(args.numcalc)
    head = decimated_head(DATA / args.subject / "head_graded_left.ply", args.faces)
    ears = {"left": ear_canal_elements(head, "left")}
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=2, radius=1.2).vertices)
    print(f"{args.subject}'s graded head decimated to {len(head.faces)} triangles (largest edge "
          f"{head.edges_unique_length.max():.1f} mm), left canal floor source ({len(ears['left'])} faces), "
          f"{args.frequency:.0f} Hz, {GRID_POINTS} far-field points")
    with tempfile.TemporaryDirectory() as scratch:
        layout = write_project(Path(scratch) / "p", head.vertices, head.faces, ears, [grid], [args.frequency],
                               source_type="Left ear")
        source = Path(scratch) / "p" / "NumCalc" / layout.sources[0]
        converged, (converged_iterations, converged_residual), seconds = solve(numcalc, source, 100000, GRID_POINTS)
        print(f"converged: {converged_iterations} iterations, relative residual {converged_residual:.2e}, {seconds:.1f} s")
        level = 20 * np.log10(np.abs(converged))
        runs = []
        for limit in sorted({max(1, round(fraction * converged_iterations)) for fraction in args.fractions}):
            if limit >= converged_iterations:
                break
            pressure, (iterations, residual), seconds = solve(numcalc, source, limit, GRID_POINTS)
            error_db = np.abs(20 * np.log10(np.abs(pressure)) - level)
            runs.append({"max_iterations": limit, "iterations": iterations, "relative_residual": residual,
                         "max_abs_db": round(float(error_db.max()), 5),
                         "p95_abs_db": round(float(np.percentile(error_db, 95)), 5)})
            print(f"  limit {limit:4d}: stopped at {iterations:4d}, relative residual {residual:.2e}: far-field level "
                  f"off by {error_db.max():.4f} dB at most (p95 {np.percentile(error_db, 95):.4f} dB), {seconds:.1f} s")
    accepted = [run["max_abs_db"] for run in runs if run["relative_residual"] <= ACCEPTED_RESIDUAL]
    print(f"runs stopped at or below the accepted residual {ACCEPTED_RESIDUAL:g}: largest level error "
          f"{max(accepted) if accepted else float('nan'):.4f} dB")
    print(json.dumps({"subject": args.subject, "faces": int(len(head.faces)), "frequency_hz": args.frequency,
                      "converged_iterations": converged_iterations, "runs": runs,
                      "max_abs_db_at_accepted_residual": max(accepted) if accepted else None,
                      "seconds": round(time.perf_counter() - started, 1)}))


if __name__ == "__main__":
    main()
