"""Benchmark: rigid-sphere accuracy and cost of the HRTF solvers.

The embedded solver (bempp-cl, Burton-Miller) and, when a NumCalc binary is given or on PATH,
NumCalc on an exported Mesh2HRTF project, both against the analytic rigid-sphere series
(radius 8.75 cm, ear element at +y, 24 directions on a 1.2 m horizontal ring).

Run: .venv/bin/python benchmarks/solve_cost.py [--numcalc /path/to/NumCalc] [--subdivisions 4]
Prints readable lines, then one JSON line with sphere_max_error_db and seconds_per_frequency.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from mesh2hrtf_io import ring_grid, write_project
from mesh2hrtf_io.analytic import rigid_sphere_hrtf
from mesh2hrtf_io.bem import estimate_cost, free_field_reference, solve_pressure
from mesh2hrtf_io.grids import spherical_to_cartesian_m

RADIUS_M = 0.0875
C, RHO = 343.0, 1.2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--numcalc", default=shutil.which("NumCalc"), help="NumCalc binary (default: PATH)")
    parser.add_argument("--subdivisions", type=int, default=3, help="icosphere subdivisions (3: 1280 triangles, 4: 5120)")
    parser.add_argument("--frequencies", type=float, nargs="+", default=[1000.0, 2000.0, 4000.0, 8000.0])
    args = parser.parse_args()

    sphere = trimesh.creation.icosphere(subdivisions=args.subdivisions, radius=RADIUS_M)
    distance = np.linalg.norm(sphere.triangles_center - [0, RADIUS_M, 0], axis=1)
    ear = np.array([int(np.argmin(distance))])
    # the analytic ear sits where the vibrating element is (its centroid direction), not on the y axis:
    # a few millimetres off the axis change the contralateral bright spot by several dB at 4-8 kHz
    ear_direction = sphere.triangles_center[ear[0]] / np.linalg.norm(sphere.triangles_center[ear[0]])
    azimuth = np.arange(0, 360, 15.0)
    ring = spherical_to_cartesian_m(azimuth, np.zeros_like(azimuth), np.full(azimuth.size, 1.2))
    cost = estimate_cost(len(sphere.vertices), len(sphere.faces), len(ring))
    print(f"sphere: {len(sphere.vertices)} vertices, {len(sphere.faces)} triangles, max edge "
          f"{1000 * sphere.edges_unique_length.max():.1f} mm; embedded estimate {cost.seconds_per_frequency:.0f} s "
          f"and {cost.memory_gb_per_frequency:.2f} GB per frequency")
    analytic = {f: 20 * np.log10(np.abs(rigid_sphere_hrtf(f, RADIUS_M, ring, ear_direction, C))) for f in args.frequencies}
    area = float(sphere.area_faces[ear].sum())

    embedded_errors, embedded_seconds = [], []
    for f in args.frequencies:
        start = time.perf_counter()
        pressure = solve_pressure(sphere.vertices, sphere.faces, ear, ring, f, C, RHO)
        embedded_seconds.append(time.perf_counter() - start)
        level = 20 * np.log10(np.abs(pressure / free_field_reference(ring, f, area, C, RHO)))
        embedded_errors.append(float(np.abs(level - analytic[f]).max()))
        print(f"embedded {f:6.0f} Hz: max error {embedded_errors[-1]:.2f} dB, {embedded_seconds[-1]:.1f} s")

    numcalc = {}
    if args.numcalc:
        with tempfile.TemporaryDirectory() as tmp:
            project = Path(tmp) / "sphere"
            write_project(project, 1000 * sphere.vertices, sphere.faces, {"left": ear}, [ring_grid("Ring", ring)],
                          args.frequencies, source_type="Left ear", speed_of_sound_m_s=C, density_kg_m3=RHO)
            source = project / "NumCalc" / "source_1"
            errors, seconds = [], []
            for step, f in enumerate(args.frequencies, start=1):
                start = time.perf_counter()
                subprocess.run([args.numcalc, "-istart", str(step), "-iend", str(step)], cwd=source, check=True,
                               capture_output=True)
                seconds.append(time.perf_counter() - start)
                data = np.loadtxt(source / "be.out" / f"be.{step}" / "pEvalGrid", skiprows=3)
                pressure = data[:, 1] + 1j * data[:, 2]
                level = 20 * np.log10(np.abs(pressure / free_field_reference(ring, f, area, C, RHO)))
                errors.append(float(np.abs(level - analytic[f]).max()))
                print(f"NumCalc  {f:6.0f} Hz: max error {errors[-1]:.2f} dB, {seconds[-1]:.1f} s")
            numcalc = {"numcalc_sphere_max_error_db": round(max(errors), 3),
                       "numcalc_seconds_per_frequency": round(float(np.mean(seconds)), 2)}
    else:
        print("NumCalc: not found (give --numcalc or put it on PATH)")
    up_to_8k = [e for f, e in zip(args.frequencies, embedded_errors) if f <= 8000.0]
    print(json.dumps({"sphere_max_error_db": round(max(up_to_8k), 3),
                      "seconds_per_frequency": round(float(np.mean(embedded_seconds)), 2),
                      "estimated_seconds_per_frequency": cost.seconds_per_frequency,
                      "n_triangles": int(len(sphere.faces)), **numcalc}))


if __name__ == "__main__":
    main()
