"""Benchmark: the embedded solver's CPU backends side by side, numba (the project's own numba pass for the system
matrix, NumPy for right-hand sides and potentials) and opencl (bempp-cl's OpenCL kernels through pocl for those).

1. A sphere of radius 8.75 cm with 1,250 vertices (the demo heads have ~1,190) and both ears vibrating, solved at
   1, 4 and 8 kHz on 793 directions at 1.2 m, each backend in a fresh process: the first frequency includes the
   process's kernel compilation or builds, the others are the steady cost; the pressures are compared.
2. The demo (`snakemake --cores 2`, 2 subjects, 8 frequencies) in a fresh copy of the workflow per backend: the
   whole run's seconds, and one demo head's seconds per frequency (results/<subject>/hrtf/embedded.json).

Run: .venv/bin/python studies/embedded_backends.py [--threads 2] [--skip-demo]
Last line: JSON with, per backend, first_frequency_seconds, seconds_per_frequency (sphere), demo_seconds,
demo_head_seconds_per_frequency, and max_relative_difference.
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

FREQUENCIES_HZ = (1000.0, 4000.0, 8000.0)
RADIUS_M = 0.0875


def head_sized_sphere():
    import trimesh  # noqa: PLC0415

    sphere = trimesh.creation.uv_sphere(radius=RADIUS_M, count=[25, 25])
    return trimesh.Trimesh(sphere.vertices, sphere.faces)  # merged poles


def child(device: str, threads: int, out: Path) -> None:
    """Solve in this process with one backend; save pressures and timings."""
    from mesh2hrtf_io.bem import solve_sources, use_device  # noqa: PLC0415

    use_device(device, threads)
    mesh = head_sized_sphere()
    ears = [[int(np.argmin(np.linalg.norm(mesh.triangles_center - [0, side * RADIUS_M, 0], axis=1)))] for side in (1, -1)]
    directions = np.random.default_rng(0).normal(size=(793, 3))
    points = 1.2 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    seconds, pressures = [], []
    for frequency in FREQUENCIES_HZ:
        start = time.perf_counter()
        pressures.append(solve_sources(mesh.vertices, mesh.faces, [(ears[0], 0.1), (ears[1], 0.1)], points,
                                       frequency, 343.0, 1.2))
        seconds.append(time.perf_counter() - start)
    np.savez(out, pressures=np.array(pressures), seconds=np.array(seconds), vertices=len(mesh.vertices))


def demo_run(device: str) -> dict:
    """The default demo run with ``hrtf.embedded_device: device`` in a fresh copy of the workflow."""
    import yaml  # noqa: PLC0415

    root = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / "project"
        for folder in ("workflow", "rules", "config"):
            shutil.copytree(root / folder, work / folder)
        config = yaml.safe_load((work / "config" / "config.yaml").read_text())
        config["hrtf"]["embedded_device"] = device
        (work / "config" / "benchmark.yaml").write_text(yaml.safe_dump(config))
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "--configfile",
                               str(work / "config" / "benchmark.yaml")], cwd=work, capture_output=True, text=True,
                              timeout=7200)
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            raise SystemExit((done.stdout + done.stderr)[-4000:])
        jobs = {path.parent.parent.name: json.loads(path.read_text())
                for path in sorted((work / "results").glob("*/hrtf/embedded.json"))}
    subject, job = next(iter(jobs.items()))
    per_frequency = job["projects"]["reference"]["seconds_per_frequency"]
    return {"seconds": round(seconds, 1), "subject": subject, "head_seconds_per_frequency": per_frequency,
            "backend": job.get("backend", {})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--skip-demo", action="store_true")
    parser.add_argument("--child", choices=["opencl", "numba"])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.threads, args.out)
        return
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for device in ("opencl", "numba"):
            out = Path(folder) / f"{device}.npz"
            subprocess.run([sys.executable, __file__, "--child", device, "--threads", str(args.threads), "--out", str(out)],
                           check=True)
            data = np.load(out)
            results[device] = {"pressures": data["pressures"], "seconds": data["seconds"], "vertices": int(data["vertices"])}
            print(f"{device}: {results[device]['vertices']} vertices, {args.threads} thread(s): first frequency "
                  f"{data['seconds'][0]:.1f} s (with kernel compilation/builds), then "
                  f"{', '.join(f'{s:.1f}' for s in data['seconds'][1:])} s per frequency (both ears)", flush=True)
    difference = np.abs(results["opencl"]["pressures"] - results["numba"]["pressures"]) / np.abs(results["numba"]["pressures"])
    print(f"largest relative difference of the pressures: {difference.max():.2e}")
    demos = {} if args.skip_demo else {device: demo_run(device) for device in ("numba", "opencl")}
    for device, demo in demos.items():
        steady = demo["head_seconds_per_frequency"][1:]
        print(f"demo with {device}: {demo['seconds']:.0f} s in all; {demo['subject']} reference head: first frequency "
              f"{demo['head_seconds_per_frequency'][0]:.1f} s, then median {np.median(steady):.2f} s per frequency "
              f"(both ears); backend {demo['backend']}", flush=True)
    print(json.dumps({
        **{f"{device}_first_frequency_seconds": round(float(r["seconds"][0]), 1) for device, r in results.items()},
        **{f"{device}_seconds_per_frequency": round(float(np.mean(r["seconds"][1:])), 2) for device, r in results.items()},
        **{f"{device}_demo_seconds": d["seconds"] for device, d in demos.items()},
        **{f"{device}_demo_head_seconds_per_frequency": round(float(np.median(d["head_seconds_per_frequency"][1:])), 2)
           for device, d in demos.items()},
        "max_relative_difference": float(difference.max()), "vertices": results["numba"]["vertices"],
        "threads": args.threads,
    }))


if __name__ == "__main__":
    main()
