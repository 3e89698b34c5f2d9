"""Benchmark: the order of the embedded solver's singular quadrature (bempp's default 4, pinned), against the rigid-sphere series.

bempp-cl integrates element pairs that touch (same element, shared edge, shared vertex) with Sauter-Schwab
quadrature of order 4 by default, which the embedded solver pins (SINGULAR_QUADRATURE_ORDER). This benchmark solves a
642-vertex icosphere (radius 8.75 cm, 14 mm edges, one vibrating element) at 2-20 kHz with orders 6 and 4 on 400
directions at 1.2 m and compares both with the analytic series: where the mesh resolves the wavelength both
orders give the same error, and where it does not (above ~8 kHz for 14 mm edges) the mesh's own error is what
remains. Then the steady seconds per frequency of each order on a 1,250-vertex sphere with both ears (1 thread).

Run: .venv/bin/python studies/singular_quadrature.py
Last line: JSON with median/max error (dB) per order and frequency, and seconds_per_frequency per order.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FREQUENCIES_HZ = (2000.0, 8000.0, 12000.0, 16000.0, 20000.0)
ORDERS = (6, 4)
RADIUS_M = 0.0875


def accuracy() -> dict:
    """Error of each order against the series (dB) on the 642-vertex sphere."""
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io import bem  # noqa: PLC0415
    from mesh2hrtf_io.analytic import rigid_sphere_hrtf  # noqa: PLC0415

    bempp = bem._bempp()
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS_M)
    ear = np.array([int(np.argmin(np.linalg.norm(sphere.triangles_center - [0, RADIUS_M, 0], axis=1)))])
    ear_direction = sphere.triangles_center[ear[0]] / np.linalg.norm(sphere.triangles_center[ear[0]])
    directions = np.random.default_rng(0).normal(size=(400, 3))
    points = 1.2 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    print(f"sphere: {len(sphere.vertices)} vertices, longest edge {1000 * sphere.edges_unique_length.max():.1f} mm")
    figures = {}
    for frequency in FREQUENCIES_HZ:
        analytic = rigid_sphere_hrtf(frequency, RADIUS_M, points, ear_direction, 343.0)
        for order in ORDERS:
            bempp.GLOBAL_PARAMETERS.quadrature.singular = order
            pressure = bem.solve_pressure(sphere.vertices, sphere.faces, ear, points, frequency, 343.0, 1.2)
            hrtf = pressure / bem.free_field_reference(points, frequency, sphere.area_faces[ear].sum(), 343.0, 1.2)
            error = np.abs(20 * np.log10(np.abs(hrtf) / np.abs(analytic)))
            khz = f"{frequency / 1000:g}khz"
            figures[f"order{order}_median_error_db_{khz}"] = round(float(np.median(error)), 3)
            figures[f"order{order}_max_error_db_{khz}"] = round(float(error.max()), 3)
            print(f"{frequency:6.0f} Hz, order {order}: error against the series median {np.median(error):.3f} dB, "
                  f"p95 {np.percentile(error, 95):.3f} dB, max {error.max():.3f} dB", flush=True)
    bempp.GLOBAL_PARAMETERS.quadrature.singular = bem.SINGULAR_QUADRATURE_ORDER
    return figures


def speed(order: int) -> float:
    """Steady seconds per frequency (both ears, 793 points, 1 thread) of a 1,250-vertex sphere at ``order``."""
    from studies.embedded_backends import head_sized_sphere  # noqa: PLC0415
    from mesh2hrtf_io import bem  # noqa: PLC0415

    bem.use_device("auto", 1)
    bem._bempp().GLOBAL_PARAMETERS.quadrature.singular = order
    mesh = head_sized_sphere()
    ears = [[int(np.argmin(np.linalg.norm(mesh.triangles_center - [0, side * RADIUS_M, 0], axis=1)))] for side in (1, -1)]
    directions = np.random.default_rng(0).normal(size=(793, 3))
    points = 1.2 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    seconds = []
    for frequency in (1000.0, 4000.0, 8000.0, 12000.0):  # the first includes the kernel builds
        start = time.perf_counter()
        bem.solve_sources(mesh.vertices, mesh.faces, [(ears[0], 0.1), (ears[1], 0.1)], points, frequency, 343.0, 1.2)
        seconds.append(time.perf_counter() - start)
    return float(np.mean(seconds[1:]))


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--speed":
        print(json.dumps({"seconds": speed(int(sys.argv[2]))}))
        return
    figures = accuracy()
    for order in ORDERS:  # each order in a fresh process, so that neither inherits the other's built kernels
        done = subprocess.run([sys.executable, __file__, "--speed", str(order)], capture_output=True, text=True,
                              check=True, cwd=ROOT)
        seconds = json.loads(done.stdout.strip().splitlines()[-1])["seconds"]
        figures[f"order{order}_seconds_per_frequency"] = round(seconds, 2)
        print(f"order {order}: {seconds:.2f} s per frequency (1,250-vertex sphere, both ears, 1 thread)", flush=True)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
