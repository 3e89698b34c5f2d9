"""Benchmark: time to set all 144 PPM parameters in Blender and read back the evaluated vertices.

Run: .venv/bin/python benchmarks/ppm_eval.py [--repeats N]
Prints readable lines, then one JSON line with n_parameters, n_vertices, eval_ms (median), and more.
Also reports the surface quality over random parameter sets: within the typical spread between listeners
(where synthetic and demo ears are drawn), uniform within the bounds, and at the bound corners; the
alignment's fold barrier keeps its fits clean out there.
"""
from __future__ import annotations

import argparse
import json
import platform
import time

import bpy  # noqa: F401  (before anything that may load pymeshlab)
import numpy as np

from ppm.model import PinnaModel
from ppm.parameters import PinnaParameters, bounds, parameter_specs, random_parameters


def flipped_faces(model: PinnaModel, params: PinnaParameters) -> int:
    """Faces whose normal turned by more than 90 degrees, parent bone excluded (it is an affine map)."""
    local = params.with_values({s.name: s.default for s in parameter_specs() if s.target == "Size-Bendy"})
    return len(model.folded_faces(model.evaluate(local)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()

    start = time.perf_counter()
    model = PinnaModel.from_template()
    build_s = time.perf_counter() - start
    lower, upper = bounds()
    rng = np.random.default_rng(0)
    sets = [PinnaParameters(rng.uniform(lower, upper)) for _ in range(args.repeats)]
    for params in sets[:10]:  # warm-up
        model.evaluate(params)
    times = []
    for params in sets:
        t0 = time.perf_counter()
        model.evaluate(params)
        times.append(time.perf_counter() - t0)
    times_ms = np.array(times) * 1e3
    print(f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, python {platform.python_version()}")
    print(f"model build (template + rig in bpy): {build_s:.2f} s")
    print(f"template: {len(model.template_vertices_mm)} vertices, {len(model.faces)} triangles")
    print(f"set 144 parameters + read evaluated vertices: median {np.median(times_ms):.2f} ms, "
          f"p95 {np.percentile(times_ms, 95):.2f} ms over {len(times_ms)} random parameter sets")

    half = [flipped_faces(model, random_parameters(rng, 0.5)) for _ in range(100)]
    typical = [flipped_faces(model, random_parameters(rng, 1.0)) for _ in range(100)]
    uniform = [flipped_faces(model, PinnaParameters(rng.uniform(lower, upper))) for _ in range(100)]
    corners = [flipped_faces(model, PinnaParameters(np.where(rng.random(len(lower)) < 0.5, lower, upper)))
               for _ in range(100)]
    print(f"flipped triangles, 100 sets uniform within half of every typical range: max {max(half)}, "
          f"sets with any: {sum(f > 0 for f in half)}")
    print(f"flipped triangles, 100 sets uniform within the typical ranges: max {max(typical)}, "
          f"sets with any: {sum(f > 0 for f in typical)}")
    print(f"flipped triangles, 100 uniform in-bound sets: max {max(uniform)}, sets with any: {sum(f > 0 for f in uniform)}")
    print(f"flipped triangles, 100 corner sets (every parameter at a bound): max {max(corners)}, "
          f"sets with any: {sum(f > 0 for f in corners)}")
    print(json.dumps({
        "n_parameters": len(parameter_specs()),
        "n_vertices": int(len(model.template_vertices_mm)),
        "eval_ms": round(float(np.median(times_ms)), 3),
        "eval_p95_ms": round(float(np.percentile(times_ms, 95)), 3),
        "build_seconds": round(build_s, 2),
        "half_range_sets_with_flips": int(sum(f > 0 for f in half)),
        "typical_sets_with_flips": int(sum(f > 0 for f in typical)),
        "typical_max_flipped_faces": int(max(typical)),
        "uniform_sets_with_flips": int(sum(f > 0 for f in uniform)),
        "uniform_max_flipped_faces": int(max(uniform)),
        "corner_sets_with_flips": int(sum(f > 0 for f in corners)),
        "corner_max_flipped_faces": int(max(corners)),
    }))


if __name__ == "__main__":
    main()
