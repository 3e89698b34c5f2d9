"""NumCalc on real graded heads: NumCalc's default cluster tree vs the level-0 cluster size we choose, the
dataset's own graded head for comparison, the cost model against every measured step, and one vs two
steps at once on this machine.

    .venv/bin/python benchmarks/numcalc_graded.py --numcalc PATH [--subject P039] [--frequencies 1000 8000 16000]

The head: the subject's SONICOM head with the PPM (fitted to its left pinna scan, packaged template)
stitched in and remeshed with the default bands. Left ear only, the workflow's sagittal-plane grid (432
points). Each step runs alone in its own copy of the source folder; finished runs are kept in
``--work``/measurements.json, so an interrupted benchmark continues where it stopped.
Last line (JSON): seconds_per_step_default, seconds_per_step_tuned, reference_seconds_per_step (means over
the steps), max_db_difference (tuned vs default, all points and steps), cost_model_max_error (relative,
all steps measured), peak_memory_gb_tuned, parallel_speedup (two steps at once vs one after the other).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"

LOG_FIELDS = {"near_nnz": r"Nonzeros of the near field matrix \.+ = (\d+)",
              "sum_nnz": r"Sum of nonzeros of the FMBEM matrices \.+ = (\d+)",
              "iterations": r"number of iterations = (\d+)",
              "assembly_s": r"Assembling the equation system\s+: (\d+)",
              "solve_s": r"Solving the equation system\s+: (\d+)",
              "post_s": r"Post processing\s+: (\d+)"}


def stitched_head(subject: str, work: Path) -> Path:
    """The subject's head with the fitted PPM pinna stitched in and remeshed (cached in work)."""
    head = work / f"{subject}_ppm_head.ply"
    if head.is_file():
        return head
    import bpy  # noqa: F401, PLC0415  (before pymeshlab)
    import trimesh  # noqa: PLC0415

    from ppm.align import align, prepare_target  # noqa: PLC0415
    from ppm.model import PinnaModel  # noqa: PLC0415
    from stitching.pipeline import remesh_files, stitch_files  # noqa: PLC0415

    model = PinnaModel.from_template()
    fit = align(model, prepare_target(SONICOM / subject / "pinna_left_crop.ply", side="left", margin_mm=3.0))
    pinna = work / f"{subject}_ppm_pinna.ply"
    trimesh.Trimesh(fit.vertices_mm, model.faces, process=False).export(pinna)
    stitch_files(SONICOM / subject / "head_graded_left.ply", pinna, work / f"{subject}_stitched.ply",
                 work / f"{subject}_stitch.json")
    remesh_files(work / f"{subject}_stitched.ply", pinna, head, work / f"{subject}_remesh.json")
    return head


def export(head: Path, folder: Path, frequencies: list[float], cluster) -> Path:
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io import write_project  # noqa: PLC0415
    from mesh2hrtf_io.grids import sagittal_grid  # noqa: PLC0415
    from mesh2hrtf_io.ear_canal import ear_canal_elements  # noqa: PLC0415

    if not (folder / "parameters.json").is_file():
        mesh = trimesh.load(head, process=False, force="mesh")
        write_project(folder, mesh.vertices, mesh.faces, {"left": ear_canal_elements(mesh, "left", source=str(head))},
                      [sagittal_grid(polar_step_deg=2.5)], frequencies, source_type="Left ear", title=head.stem,
                      numcalc_cluster_size=cluster)
    return folder


def _isolated_source(project: Path, tag: str, work: Path) -> Path:
    """A fresh copy of NumCalc/source_1 whose relative mesh paths still resolve (meshes linked)."""
    root = work / "runs" / tag
    if root.exists():
        shutil.rmtree(root)
    (root / "NumCalc" / "source_1").mkdir(parents=True)
    for name in ("ObjectMeshes", "EvaluationGrids"):
        (root / name).symlink_to(project.resolve() / name)
    shutil.copy(project / "NumCalc" / "source_1" / "NC.inp", root / "NumCalc" / "source_1" / "NC.inp")
    return root / "NumCalc" / "source_1"


def _start(numcalc: Path, source: Path, step: int) -> subprocess.Popen:
    return subprocess.Popen([str(numcalc), "-istart", str(step), "-iend", str(step)], cwd=source,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _finish(process: subprocess.Popen, source: Path, step: int, started: float) -> dict:
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - started
    log = (source / f"NC{step}-{step}.out").read_text(errors="replace")
    record = {"seconds": round(seconds, 1), "peak_gb": round(usage.ru_maxrss / 1e6, 3), "exit": process.returncode}
    for key, pattern in LOG_FIELDS.items():
        match = re.search(pattern, log)
        record[key] = int(match.group(1)) if match else None
    levels = re.search(r"Level\s+Num\. of clusters.*?\n((?:\s+\d+\s+\d+.*\n)+)", log)
    record["levels"] = len(levels.group(1).strip().split("\n")) if levels else 1
    return record


def _pressure(source: Path, step: int) -> list:
    from mesh2hrtf_io.results import read_eval_grid_pressure  # noqa: PLC0415

    p = read_eval_grid_pressure(source, step)
    return [p.real.tolist(), p.imag.tolist()]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--numcalc", default=None, help="NumCalc binary (default: PATH, then .venv/bin)")
    parser.add_argument("--subject", default="P039")
    parser.add_argument("--frequencies", type=float, nargs="+", default=[1000.0, 8000.0, 16000.0])
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "benchmarks" / "numcalc_graded")
    parser.add_argument("--no-parallel", action="store_true", help="skip the two-steps-at-once measurement")
    args = parser.parse_args()

    from mesh2hrtf_io.numcalc import NumCalcError, estimate_memory, find_numcalc  # noqa: PLC0415
    from mesh2hrtf_io.numcalc_cost import predict_steps, tree_of_project  # noqa: PLC0415
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415

    try:
        numcalc = find_numcalc(args.numcalc)
    except NumCalcError as exc:
        print(f"numcalc_graded: {exc}", file=sys.stderr)
        return 2
    args.work.mkdir(parents=True, exist_ok=True)
    store = args.work / "measurements.json"
    runs = json.loads(store.read_text()) if store.is_file() else {}
    head = stitched_head(args.subject, args.work)
    projects = {"default": export(head, args.work / "ppm_default", args.frequencies, 0.0),
                "tuned": export(head, args.work / "ppm_tuned", args.frequencies, "auto"),
                "reference": export(SONICOM / args.subject / "head_graded_left.ply", args.work / "reference",
                                    args.frequencies, 0.0)}
    predictions = {}
    for name, project_dir in projects.items():
        project = read_project(project_dir)
        tree = tree_of_project(project.vertices_m, project.faces, project.sources[0].folder / "NC.inp")
        memory = [e.memory_gb for e in estimate_memory(numcalc, project.sources[0].folder)]
        predictions[name] = predict_steps(project.vertices_m, project.faces, tree, args.frequencies, memory)
        print(f"{name}: {len(project.faces)} elements, level-0 cluster "
              f"{'NumCalc default' if tree.written_m == 0 else f'{tree.written_m * 1000:.1f} mm'}, {tree.levels} levels, "
              f"finest clusters {tree.finest_m * 1000:.1f} mm, mean element length {tree.element_length_m * 1000:.2f} mm")
    for name, project_dir in projects.items():
        for step, frequency in enumerate(args.frequencies, start=1):
            tag = f"{name}_{int(frequency)}"
            if tag in runs:
                continue
            source = _isolated_source(project_dir, tag, args.work)
            started = time.perf_counter()
            record = _finish(_start(numcalc, source, step), source, step, started)
            record["pressure"] = _pressure(source, step)
            runs[tag] = record
            store.write_text(json.dumps(runs))
            print(f"  measured {tag}: {record['seconds']} s", flush=True)
    if not args.no_parallel and "parallel" not in runs and len(args.frequencies) >= 2:
        steps = [len(args.frequencies) - 1, len(args.frequencies)]
        sources = [_isolated_source(projects["tuned"], f"parallel_{k}", args.work) for k in steps]
        started = time.perf_counter()
        processes = [_start(numcalc, source, k) for source, k in zip(sources, steps)]
        records = [_finish(p, source, k, started) for p, source, k in zip(processes, sources, steps)]
        runs["parallel"] = {"steps": steps, "wall_s": round(time.perf_counter() - started, 1),
                            "seconds": [r["seconds"] for r in records]}
        store.write_text(json.dumps(runs))

    print(f"\n{'run':<18} {'measured s':>10} {'predicted s':>11} {'error':>7} {'peak GB':>8} {'est. GB':>8} {'levels':>6} "
          f"{'near nnz M':>10} {'pred. M':>8} {'iter.':>5} {'asm/solve/post s':>17}")
    errors, seconds = [], {name: [] for name in projects}
    for name in projects:
        for step, frequency in enumerate(args.frequencies):
            record, predicted = runs[f"{name}_{int(frequency)}"], predictions[name][step]
            error = predicted.seconds / record["seconds"] - 1
            errors.append(error)
            seconds[name].append(record["seconds"])
            print(f"{name + ' ' + str(int(frequency)):<18} {record['seconds']:>10.1f} {predicted.seconds:>11.1f} "
                  f"{error:>+7.1%} {record['peak_gb']:>8.2f} {predicted.memory_gb:>8.2f} {record['levels']:>6} "
                  f"{(record['near_nnz'] or 0) / 1e6:>10.1f} {predicted.near_pairs_million:>8.1f} "
                  f"{record['iterations'] or 0:>5} {record['assembly_s']}/{record['solve_s']}/{record['post_s']:>3}")
    differences = []
    for frequency in args.frequencies:
        default = np.array(runs[f"default_{int(frequency)}"]["pressure"])
        tuned = np.array(runs[f"tuned_{int(frequency)}"]["pressure"])
        ratio = np.abs(tuned[0] + 1j * tuned[1]) / np.abs(default[0] + 1j * default[1])
        differences.append(float(np.abs(20 * np.log10(ratio)).max()))
        print(f"tuned vs default at {frequency:g} Hz: max |difference| {differences[-1]:.4f} dB")
    speedup = None
    if "parallel" in runs:
        parallel = runs["parallel"]
        sequential = sum(runs[f"tuned_{int(args.frequencies[k - 1])}"]["seconds"] for k in parallel["steps"])
        speedup = round(sequential / parallel["wall_s"], 3)
        print(f"two tuned steps ({', '.join(str(int(args.frequencies[k - 1])) for k in parallel['steps'])} Hz) at once: "
              f"{parallel['wall_s']} s wall (each {parallel['seconds']} s) vs {sequential:.1f} s one after the other: "
              f"speed-up {speedup}")
    summary = {"seconds_per_step_default": round(float(np.mean(seconds["default"])), 1),
               "seconds_per_step_tuned": round(float(np.mean(seconds["tuned"])), 1),
               "reference_seconds_per_step": round(float(np.mean(seconds["reference"])), 1),
               "max_db_difference": round(max(differences), 4),
               "cost_model_max_error": round(float(np.max(np.abs(errors))), 3),
               "peak_memory_gb_tuned": max(runs[f"tuned_{int(f)}"]["peak_gb"] for f in args.frequencies),
               "parallel_speedup": speedup, "subject": args.subject, "frequencies_hz": args.frequencies,
               "tuned_over_default": round(float(np.mean(seconds["tuned"]) / np.mean(seconds["default"])), 3)}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
