"""Benchmark: accuracy and cost of the HRTF solvers.

1. Rigid sphere (radius 8.75 cm, 1280 triangles, one vibrating element, 24 directions on a 1.2 m
   horizontal ring): embedded solver (bempp-cl, Burton-Miller) and, when available, NumCalc on the
   exported Mesh2HRTF project, against the analytic series (ear at the element's centroid direction).
2. Mesh2HRTF's example head (17,432 triangles, left ear): estimated against measured seconds per
   frequency for the embedded solver (one frequency) and for NumCalc (several, when available), with
   NumCalc's own memory estimate.

Run: .venv/bin/python benchmarks/solve_cost.py [--numcalc PATH] [--skip-head-embedded]
Last line: JSON with sphere_max_error_db (embedded, up to 8 kHz) and seconds_per_frequency (embedded,
example head), plus the NumCalc figures when it ran.
"""
from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from mesh2hrtf_io import ring_grid, sagittal_grid, write_project
from mesh2hrtf_io.analytic import rigid_sphere_hrtf
from mesh2hrtf_io.bem import estimate_cost, free_field_reference, solve_pressure
from mesh2hrtf_io.cost import numcalc_seconds
from mesh2hrtf_io.embedded import solve_project_embedded
from mesh2hrtf_io.grids import spherical_to_cartesian_m
from mesh2hrtf_io.numcalc import estimate_memory, find_numcalc, run_step
from mesh2hrtf_io.results import read_eval_grid_pressure
from mesh2hrtf_io.ear_canal import ear_canal_elements

RADIUS_M = 0.0875
C, RHO = 343.0, 1.2
HEAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "heads" / "mesh2hrtf_example_head_5mm.ply"


def sphere_part(frequencies, numcalc):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS_M)
    ear = np.array([int(np.argmin(np.linalg.norm(sphere.triangles_center - [0, RADIUS_M, 0], axis=1)))])
    # the analytic ear sits where the vibrating element is (its centroid direction), not on the y axis:
    # a few millimetres off the axis change the contralateral bright spot by several dB at 4-8 kHz
    ear_direction = sphere.triangles_center[ear[0]] / np.linalg.norm(sphere.triangles_center[ear[0]])
    azimuth = np.arange(0, 360, 15.0)
    ring = spherical_to_cartesian_m(azimuth, np.zeros_like(azimuth), np.full(azimuth.size, 1.2))
    area = float(sphere.area_faces[ear].sum())
    analytic = {f: 20 * np.log10(np.abs(rigid_sphere_hrtf(f, RADIUS_M, ring, ear_direction, C))) for f in frequencies}
    print(f"sphere: {len(sphere.vertices)} vertices, {len(sphere.faces)} triangles, max edge "
          f"{1000 * sphere.edges_unique_length.max():.1f} mm, 24 ring directions")
    errors = {"embedded": []}
    for f in frequencies:
        start = time.perf_counter()
        pressure = solve_pressure(sphere.vertices, sphere.faces, ear, ring, f, C, RHO)
        level = 20 * np.log10(np.abs(pressure / free_field_reference(ring, f, area, C, RHO)))
        errors["embedded"].append(float(np.abs(level - analytic[f]).max()))
        print(f"  embedded {f:6.0f} Hz: max error {errors['embedded'][-1]:.2f} dB ({time.perf_counter() - start:.1f} s)")
    if numcalc:
        errors["numcalc"] = []
        with tempfile.TemporaryDirectory() as tmp:
            project = Path(tmp) / "sphere"
            write_project(project, 1000 * sphere.vertices, sphere.faces, {"left": ear}, [ring_grid("Ring", ring)],
                          frequencies, source_type="Left ear", speed_of_sound_m_s=C, density_kg_m3=RHO)
            source = project / "NumCalc" / "source_1"
            for step, f in enumerate(frequencies, start=1):
                run_step(numcalc, source, step, len(ring))
                pressure = read_eval_grid_pressure(source, step, len(ring))
                level = 20 * np.log10(np.abs(pressure / free_field_reference(ring, f, area, C, RHO)))
                errors["numcalc"].append(float(np.abs(level - analytic[f]).max()))
                print(f"  NumCalc  {f:6.0f} Hz: max error {errors['numcalc'][-1]:.2f} dB")
    return errors


def head_part(numcalc, embedded: bool, numcalc_frequencies):
    head = trimesh.load(HEAD, process=False)
    ear = ear_canal_elements(head, "left", source=str(HEAD))
    grid = sagittal_grid(polar_step_deg=5.0)
    print(f"example head: {len(head.vertices)} vertices, {len(head.faces)} triangles, left ear element {ear.tolist()}, "
          f"{len(grid.points_m)} grid points")
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        if embedded:
            project = Path(tmp) / "embedded"
            write_project(project, head.vertices, head.faces, {"left": ear}, [grid], [1000.0], source_type="Left ear")
            cost = estimate_cost(len(head.vertices), len(head.faces), len(grid.points_m))
            summary = solve_project_embedded(project)
            result.update(embedded_estimated_seconds=cost.seconds_per_frequency,
                          embedded_estimated_memory_gb=cost.memory_gb_per_frequency,
                          seconds_per_frequency=round(summary["measured_seconds_per_step"], 1))
            print(f"  embedded 1000 Hz: estimated {cost.seconds_per_frequency:.0f} s / {cost.memory_gb_per_frequency:.1f} "
                  f"GB, measured {summary['measured_seconds_per_step']:.0f} s (includes numba compilation)")
        if numcalc:
            project = Path(tmp) / "numcalc"
            write_project(project, head.vertices, head.faces, {"left": ear}, [grid], numcalc_frequencies,
                          source_type="Left ear")
            source = project / "NumCalc" / "source_1"
            memory = estimate_memory(numcalc, source)
            measured = []
            for step, f in enumerate(numcalc_frequencies, start=1):
                status = run_step(numcalc, source, step, len(grid.points_m))
                measured.append(status["attempts"][-1]["seconds"])
                print(f"  NumCalc {f:6.0f} Hz: estimated {numcalc_seconds(len(head.faces), f):.0f} s and "
                      f"{memory[step - 1].memory_gb:.2f} GB (NumCalc -estimate_ram), measured {measured[-1]:.1f} s")
            result.update(numcalc_seconds_per_frequency={str(int(f)): s for f, s in zip(numcalc_frequencies, measured)},
                          numcalc_estimated_seconds={str(int(f)): round(numcalc_seconds(len(head.faces), f), 1)
                                                     for f in numcalc_frequencies},
                          numcalc_memory_gb=max(m.memory_gb for m in memory))
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--numcalc", default=shutil.which("NumCalc"), help="NumCalc binary (default: PATH)")
    parser.add_argument("--frequencies", type=float, nargs="+", default=[1000.0, 2000.0, 4000.0, 8000.0])
    parser.add_argument("--head-numcalc-frequencies", type=float, nargs="+", default=[1000.0, 4000.0, 8000.0])
    parser.add_argument("--skip-head-embedded", action="store_true", help="skip the ~6 min embedded head step")
    args = parser.parse_args()
    numcalc = find_numcalc(args.numcalc) if args.numcalc else None
    if not numcalc:
        print("NumCalc: not found (give --numcalc or put it on PATH); embedded solver only")
    errors = sphere_part(args.frequencies, numcalc)
    head = head_part(numcalc, not args.skip_head_embedded, args.head_numcalc_frequencies)
    up_to_8k = [e for f, e in zip(args.frequencies, errors["embedded"]) if f <= 8000.0]
    out = {"sphere_max_error_db": round(max(up_to_8k), 3), "seconds_per_frequency": head.pop("seconds_per_frequency", None)}
    if "numcalc" in errors:
        out["numcalc_sphere_max_error_db"] = round(max(errors["numcalc"]), 3)
    print(json.dumps(out | head))


if __name__ == "__main__":
    main()
