"""Benchmark: the embedded BEM solver on a GPU (CuPy), on SONICOM P143's full-resolution heads, against NumCalc.

Three stages, so that the GPU machine needs neither bempp-cl nor any mesh library (only NumPy, SciPy and CuPy):

1. ``prepare`` (here, with the project installed): exports the Mesh2HRTF projects of P143's heads whose 40 NumCalc
   steps are committed (evaluation/sonicom/steps) and writes per head the solver's frequency-independent arrays
   (``surface.npz``, :class:`mesh2hrtf_io.bem_arrays.SurfaceArrays`) and the problem (evaluation points, ear
   elements, frequencies); also a demo-sized head for the CPU-twin check and a fine rigid sphere.
2. ``solve`` (on the GPU): the twin check (the system matrix on CuPy against NumPy, same code), cuSOLVER's LU
   against PyTorch's, the sphere, then every head, all 40 frequencies, both in one process; pressures and
   per-phase seconds to ``--out``.
3. ``numcalc-sphere`` (here, optional, NumCalc installed): the same sphere by NumCalc, so the report can say which
   solver is nearer the analytic series.
4. ``report`` (here): per step the magnitude difference to NumCalc's committed steps over the 793 directions
   (median, p95, max dB), the sphere against the analytic series (and the CPU solver), and QE/PE by the paper's
   protocol (the NumCalc ``original`` as reference and template, S at 8 % QE).

Run: ``.venv/bin/python benchmarks/gpu_solve.py`` where a GPU is (all three stages); without one it says so and
exits 2. The results of the last GPU run are kept in benchmarks/results/gpu_solve/ (``report`` reads them).
Last line: JSON with gpu, n_vertices, seconds_per_frequency, seconds_per_head, max_median_db, max_p95_db,
delta_qe_pp, delta_pe_deg, and the sphere's and the twin's figures.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mesh2hrtf_io import bem_arrays  # noqa: E402

KEPT = ROOT / "benchmarks" / "results" / "gpu_solve"
SUBJECT = "P143"
HEADS = ("original", "ppm", "own_pinna", "default_ppm")
SPHERE_RADIUS_M = 0.0875
SPHERE_FREQUENCIES_HZ = (2000.0, 8000.0, 12000.0, 16000.0)
GOAL_FREQUENCY_HZ = 16000.0


# --- prepare (CPU, project installed) ---------------------------------------------------------------------------

def _arrays_of(vertices_m: np.ndarray, faces: np.ndarray):
    from mesh2hrtf_io import bem  # noqa: PLC0415

    bempp = bem._bempp()
    grid = bempp.Grid(np.ascontiguousarray(vertices_m.T), np.ascontiguousarray(faces.T.astype(np.uint32)))
    p1 = bempp.function_space(grid, "P", 1)
    return bem_arrays.surface_arrays(grid, p1, bem.REGULAR_QUADRATURE_ORDER, bem.SINGULAR_QUADRATURE_ORDER)


def prepare(out: Path, heads: list[str]) -> None:
    """Export P143's projects (snakemake, config/paper_sonicom.yaml) and write the GPU's inputs to ``out``."""
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415

    out.mkdir(parents=True, exist_ok=True)
    targets = [f"results/{SUBJECT}/hrtf/{head}/project" for head in heads]
    subprocess.run([sys.executable, "-m", "snakemake", "--configfile", "config/paper_sonicom.yaml", "--cores", "2",
                    *targets], cwd=ROOT, check=True, capture_output=True)
    for head in heads:
        project = read_project(ROOT / f"results/{SUBJECT}/hrtf/{head}/project")
        start = time.perf_counter()
        arrays = _arrays_of(project.vertices_m, project.faces)
        arrays.save(out / f"{head}_surface.npz")
        source = project.sources[0]
        np.savez(out / f"{head}_problem.npz", points_m=project.evaluation_points_m,
                 ear_elements=source.elements, velocity_m_s=source.velocity_m_s,
                 frequencies_hz=project.frequencies_hz, speed_of_sound_m_s=project.speed_of_sound_m_s,
                 density_kg_m3=project.density_kg_m3, n_vertices=len(project.vertices_m))
        print(f"{head}: {len(project.vertices_m)} vertices, {len(project.faces)} triangles, "
              f"{len(project.frequencies_hz)} frequencies, {len(project.evaluation_points_m)} points; arrays in "
              f"{time.perf_counter() - start:.0f} s", flush=True)
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=SPHERE_RADIUS_M)
    ear = int(np.argmin(np.linalg.norm(sphere.triangles_center - [0, SPHERE_RADIUS_M, 0], axis=1)))
    _arrays_of(sphere.vertices, sphere.faces).save(out / "sphere_surface.npz")
    directions = np.random.default_rng(0).normal(size=(200, 3))
    np.savez(out / "sphere_problem.npz", points_m=1.2 * directions / np.linalg.norm(directions, axis=1, keepdims=True),
             ear_elements=[ear], velocity_m_s=0.1, frequencies_hz=np.array(SPHERE_FREQUENCIES_HZ),
             speed_of_sound_m_s=343.0, density_kg_m3=1.2, n_vertices=len(sphere.vertices),
             ear_centre_m=sphere.triangles_center[ear], ear_area_m2=sphere.area_faces[ear])
    demo = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    _arrays_of(demo.vertices * [0.095, 0.076, 0.115], demo.faces).save(out / "twin_surface.npz")
    print(f"inputs in {out} ({sum(p.stat().st_size for p in out.iterdir()) / 1e6:.1f} MB)")


# --- solve (GPU) ------------------------------------------------------------------------------------------------

def _sync(backend):
    backend.synchronize()
    return time.perf_counter()


def solve(inputs: Path, out: Path, backend_name: str, budget_s: float, heads: list[str],
          assembly: str = "fused") -> None:
    """Solve the prepared heads on ``backend_name`` (cupy; numpy for a dry run), writing results as they come."""
    start_all = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    backend = bem_arrays.cupy_backend() if backend_name == "cupy" else bem_arrays.numpy_backend()
    info = {"backend": backend_name}
    if backend_name == "cupy":
        import cupy  # noqa: PLC0415

        properties = cupy.cuda.runtime.getDeviceProperties(0)
        name = properties["name"]
        info.update(gpu=name.decode() if isinstance(name, bytes) else str(name), cupy=cupy.__version__,
                    memory_gb=round(cupy.cuda.Device(0).mem_info[1] / 1e9, 1))
    print(json.dumps(info), flush=True)
    budget = 24e9 if backend_name == "cupy" else 0.3e9
    # 1. the CPU twin: the same system matrix on NumPy and on this backend
    twin = bem_arrays.SurfaceArrays.load(inputs / "twin_surface.npz")
    k = 2 * np.pi * 12000.0 / 343.0
    on_cpu = bem_arrays.system_matrix(bem_arrays.DeviceSurface(twin, bem_arrays.numpy_backend()), k, 1j / k,
                                      budget_bytes=0.3e9)
    on_backend = backend.to_host(bem_arrays.system_matrix(bem_arrays.DeviceSurface(twin, backend), k, 1j / k,
                                                          budget_bytes=budget))
    info["twin_max_relative_difference"] = float(np.abs(on_backend - on_cpu).max() / np.abs(on_cpu).max())
    info["twin_n"] = int(twin.dof_count)
    print(f"twin: n = {twin.dof_count}, max |GPU - CPU| / max |CPU| = {info['twin_max_relative_difference']:.2e}",
          flush=True)
    # 1b. the fused far-pair kernel (mesh2hrtf_io/bem_fused.py) against the same CPU twin; the heads use it where it
    # agrees to 1e-10 (else the array code, with the reason kept)
    fused = False
    if backend_name == "cupy" and assembly == "fused":
        try:
            on_fused = backend.to_host(bem_arrays.system_matrix(bem_arrays.DeviceSurface(twin, backend), k, 1j / k,
                                                                budget_bytes=budget, fused=True))
            info["fused_twin_max_relative_difference"] = float(np.abs(on_fused - on_cpu).max() / np.abs(on_cpu).max())
            fused = info["fused_twin_max_relative_difference"] < 1e-10
            info["assembly"] = "fused" if fused else "arrays (the fused kernel missed the twin by 1e-10)"
        except Exception as error:  # numba-cuda missing or failing on this machine: the array code solves
            info["assembly"] = f"arrays (the fused kernel failed: {type(error).__name__}: {error})"
        print(f"fused kernel: {info['assembly']}, twin difference {info.get('fused_twin_max_relative_difference')}",
              flush=True)
    else:
        info["assembly"] = "arrays"
    # 2. the LU: cuSOLVER (cupyx) against PyTorch at the head's size
    if backend_name == "cupy":
        info["lu"] = _lu_comparison(15735)
        print(f"LU n = 15735 complex128: {info['lu']}", flush=True)
    (out / "info.json").write_text(json.dumps(info, indent=2))
    # 3. the sphere and the heads
    for head in ["sphere", *heads]:
        if not (inputs / f"{head}_surface.npz").is_file():
            continue
        if time.perf_counter() - start_all > budget_s:
            print(f"{head}: skipped (time budget of {budget_s:.0f} s spent)", flush=True)
            continue
        surface = bem_arrays.SurfaceArrays.load(inputs / f"{head}_surface.npz")
        problem = np.load(inputs / f"{head}_problem.npz")
        t0 = _sync(backend)
        dev = bem_arrays.DeviceSurface(surface, backend)
        setup_s = _sync(backend) - t0
        pressures, phases = [], []
        for frequency in problem["frequencies_hz"]:
            timings: dict[str, float] = {}
            t0 = _sync(backend)
            [pressure] = bem_arrays.solve_sources_arrays(
                dev, [(problem["ear_elements"], float(problem["velocity_m_s"]))], problem["points_m"],
                float(frequency), float(problem["speed_of_sound_m_s"]), float(problem["density_kg_m3"]),
                timings=timings, budget_bytes=budget, fused=fused)
            timings["total"] = _sync(backend) - t0
            pressures.append(pressure)
            phases.append(timings)
            print(f"{head} {frequency:7.0f} Hz: " + ", ".join(f"{k} {v:.2f}" for k, v in timings.items()) + " s",
                  flush=True)
            if time.perf_counter() - start_all > budget_s + 60 and head != "sphere":
                print(f"{head}: stopped after {len(pressures)} frequencies (time budget)", flush=True)
                break
        pool_gb = 0.0
        if backend_name == "cupy":
            import cupy  # noqa: PLC0415

            pool_gb = cupy.get_default_memory_pool().total_bytes() / 1e9  # the pool keeps what the peak took
            cupy.get_default_memory_pool().free_all_blocks()
        np.savez(out / f"{head}_pressures.npz", pressure=np.array(pressures), memory_pool_gb=pool_gb,
                 frequencies_hz=problem["frequencies_hz"][:len(pressures)],
                 seconds=np.array([p["total"] for p in phases]), setup_seconds=setup_s,
                 phases_json=json.dumps(phases), n_vertices=int(surface.dof_count), n_elements=surface.n_elements)
    print(f"all done in {time.perf_counter() - start_all:.0f} s", flush=True)


def _lu_comparison(n: int) -> dict:
    """Seconds of a complex128 LU of an n x n matrix by cuSOLVER through cupyx and through PyTorch."""
    import cupy  # noqa: PLC0415
    import cupyx.scipy.linalg  # noqa: PLC0415

    result = {}
    rng = cupy.random.default_rng(0)
    a = rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)) + n * cupy.eye(n)
    for attempt in range(2):
        b = a.copy()
        cupy.cuda.Stream.null.synchronize()
        t0 = time.perf_counter()
        cupyx.scipy.linalg.lu_factor(b, overwrite_a=True, check_finite=False)
        cupy.cuda.Stream.null.synchronize()
        result["cupy_s"] = round(time.perf_counter() - t0, 3)
    del b
    try:
        import torch  # noqa: PLC0415

        t = torch.as_tensor(a, device="cuda")
        for attempt in range(2):
            torch.cuda.synchronize()
            t0 = time.perf_counter()
            torch.linalg.lu_factor(t)
            torch.cuda.synchronize()
            result["torch_s"] = round(time.perf_counter() - t0, 3)
    except Exception as exc:  # noqa: BLE001 - the comparison is optional
        result["torch_error"] = str(exc)[:200]
    return result


# --- NumCalc on the sphere (CPU, NumCalc installed): which solver is nearer the series -------------------------

def numcalc_sphere(inputs: Path, out: Path, numcalc: str | None) -> None:
    """Solve the prepared sphere (same mesh, ear element, points and frequencies as the GPU's) with NumCalc."""
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io import sphere_grid, write_project  # noqa: PLC0415
    from mesh2hrtf_io.numcalc import solve_project_numcalc  # noqa: PLC0415
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415
    from mesh2hrtf_io.results import read_eval_grid_pressure  # noqa: PLC0415

    problem = np.load(inputs / "sphere_problem.npz")
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=SPHERE_RADIUS_M * 1000.0)
    folder = out / "numcalc_sphere_project"
    if not folder.is_dir():
        write_project(folder, sphere.vertices, sphere.faces, {"left": np.asarray(problem["ear_elements"])},
                      [sphere_grid("Directions", problem["points_m"])], list(problem["frequencies_hz"]),
                      source_type="Left ear", speed_of_sound_m_s=343.0, density_kg_m3=1.2, title="sphere")
    start = time.perf_counter()
    solve_project_numcalc(folder, numcalc)
    project = read_project(folder)
    pressure = np.array([read_eval_grid_pressure(project.sources[0].folder, step, len(problem["points_m"]))
                         for step in range(1, len(project.frequencies_hz) + 1)])
    np.savez(out / "sphere_numcalc_pressures.npz", pressure=pressure, frequencies_hz=project.frequencies_hz,
             seconds=time.perf_counter() - start)
    shutil.rmtree(folder)


# --- report (CPU, project installed) ----------------------------------------------------------------------------

def _step_store_pressures(head: str) -> tuple[np.ndarray, list[float]]:
    """NumCalc's committed pressures of a head (steps, points) and each step's CPU seconds."""
    from mesh2hrtf_io.step_store import project_fingerprint, solve_seconds, stored_status  # noqa: PLC0415

    project = ROOT / f"results/{SUBJECT}/hrtf/{head}/project"
    fingerprint = project_fingerprint(project, 1)
    store = ROOT / "evaluation" / "sonicom" / "steps" / SUBJECT / head / "source_1"
    pressures, seconds = [], []
    for path in sorted(store.glob("step_*.npz")):
        with np.load(path) as step:
            if str(step["fingerprint"]) != fingerprint:
                raise SystemExit(f"{path}: stored for another project than results/{SUBJECT}/hrtf/{head}/project")
            pressures.append(step["pressure"])
        seconds.append(solve_seconds(stored_status(store.parent, 1, int(path.stem.split("_")[1]))))
    return np.array(pressures), seconds


def _sofa_of(head: str, pressures: np.ndarray, folder: Path) -> Path:
    """A left-ear HRTF SOFA of ``pressures`` (steps, points) collected as the workflow collects, in a copy of the
    head's project (:func:`mesh2hrtf_io.hrtf_job.collect_pressures`)."""
    from mesh2hrtf_io.hrtf_job import collect_pressures  # noqa: PLC0415

    return collect_pressures(ROOT / f"results/{SUBJECT}/hrtf/{head}/project", pressures, folder / head)


def paper_protocol(reference_hrtf: Path, conditions: dict[str, Path]) -> dict:
    """QE/PE of each condition with the reference as template, S calibrated to 8 % QE on it: the paper's protocol
    (:func:`reporting.paper_protocol.paper_protocol`, the right ear from the subject's dataset HRIRs)."""
    from reporting.paper_protocol import paper_protocol as protocol  # noqa: PLC0415

    return protocol(reference_hrtf, conditions, ROOT.parent / "shared/data/sonicom" / SUBJECT / "hrir_mesh2hrtf_48k.sofa")


def _sphere_errors(solved, problem, solver: str) -> dict:
    """Per frequency, |solved - series| (dB) over the sphere's directions: median, p95, max; printed as it goes."""
    from mesh2hrtf_io.analytic import rigid_sphere_hrtf  # noqa: PLC0415
    from mesh2hrtf_io.bem import free_field_reference  # noqa: PLC0415

    ear_direction = problem["ear_centre_m"] / np.linalg.norm(problem["ear_centre_m"])
    errors = {}
    for frequency, pressure in zip(solved["frequencies_hz"], solved["pressure"]):
        hrtf = pressure / free_field_reference(problem["points_m"], frequency, float(problem["ear_area_m2"]), 343.0, 1.2)
        analytic = rigid_sphere_hrtf(float(frequency), SPHERE_RADIUS_M, problem["points_m"], ear_direction, 343.0)
        error = np.abs(20 * np.log10(np.abs(hrtf) / np.abs(analytic)))
        errors[f"{frequency:.0f}"] = {"median_db": round(float(np.median(error)), 3),
                                      "p95_db": round(float(np.percentile(error, 95)), 3),
                                      "max_db": round(float(error.max()), 3)}
        print(f"sphere ({int(problem['n_vertices'])} vertices) {frequency:6.0f} Hz: |{solver} - series| median "
              f"{np.median(error):.3f} dB, p95 {np.percentile(error, 95):.3f} dB, max {error.max():.3f} dB")
    return errors


def report(inputs: Path, results: Path) -> dict:
    import tempfile  # noqa: PLC0415

    info = json.loads((results / "info.json").read_text())
    figures: dict = {"gpu": info.get("gpu", info["backend"]), "twin_max_relative_difference":
                     info["twin_max_relative_difference"], "lu": info.get("lu")}
    # the sphere against the series, solved on the GPU and (numcalc-sphere stage) by NumCalc
    problem = np.load(inputs / "sphere_problem.npz")
    figures["sphere_error_db"] = _sphere_errors(np.load(results / "sphere_pressures.npz"), problem, "GPU")
    if (results / "sphere_numcalc_pressures.npz").is_file():
        figures["sphere_numcalc_error_db"] = _sphere_errors(np.load(results / "sphere_numcalc_pressures.npz"),
                                                            problem, "NumCalc")
    sphere_errors = figures["sphere_error_db"]
    solved = [h for h in HEADS if (results / f"{h}_pressures.npz").is_file()]
    per_head = {}
    with tempfile.TemporaryDirectory() as tmp:
        sofa_gpu, sofa_numcalc = {}, {}
        for head in solved:
            gpu = np.load(results / f"{head}_pressures.npz")
            numcalc, cpu_seconds = _step_store_pressures(head)
            steps = len(gpu["pressure"])
            difference = np.abs(20 * np.log10(np.abs(gpu["pressure"]) / np.abs(numcalc[:steps])))  # (steps, points)
            rows = []
            for index, frequency in enumerate(gpu["frequencies_hz"]):
                row = {"frequency_hz": float(frequency), "median_db": float(np.median(difference[index])),
                       "p95_db": float(np.percentile(difference[index], 95)), "max_db": float(difference[index].max()),
                       "gpu_seconds": float(gpu["seconds"][index]), "numcalc_cpu_seconds": cpu_seconds[index]}
                rows.append(row)
                print(f"{head} {frequency:7.0f} Hz: |GPU - NumCalc| median {row['median_db']:.3f} dB, p95 "
                      f"{row['p95_db']:.3f} dB, max {row['max_db']:.2f} dB; GPU {row['gpu_seconds']:.2f} s, NumCalc "
                      f"{row['numcalc_cpu_seconds']:.0f} CPU s")
            up_to = [r for r in rows if r["frequency_hz"] <= GOAL_FREQUENCY_HZ]
            per_head[head] = {
                "n_vertices": int(gpu["n_vertices"]), "n_elements": int(gpu["n_elements"]), "steps": steps,
                "seconds_per_frequency": float(np.mean(gpu["seconds"])), "seconds_per_head": float(np.sum(gpu["seconds"])),
                "numcalc_cpu_hours": sum(cpu_seconds) / 3600.0,
                "max_median_db": max(r["median_db"] for r in up_to), "max_p95_db": max(r["p95_db"] for r in up_to),
                "steps_table": rows}
            if steps == len(numcalc):
                sofa_gpu[head] = _sofa_of(f"{head}", gpu["pressure"], Path(tmp) / "gpu")
                sofa_numcalc[head] = _sofa_of(f"{head}", numcalc, Path(tmp) / "numcalc")
        protocol = {}
        if "original" in sofa_numcalc and "original" in sofa_gpu:
            # the GPU's own solve of the unchanged head heard against NumCalc's (S on NumCalc's, paper protocol)
            protocol["numcalc_reference"] = paper_protocol(sofa_numcalc["original"],
                                                           {f"{h}_gpu": sofa_gpu[h] for h in sofa_gpu}
                                                           | {f"{h}_numcalc": sofa_numcalc[h] for h in sofa_numcalc
                                                              if h != "original"})
            # every condition solved by the GPU, its own original as reference (the paper's protocol, one solver)
            protocol["gpu_reference"] = paper_protocol(sofa_gpu["original"],
                                                       {h: sofa_gpu[h] for h in sofa_gpu if h != "original"})
    figures["heads"] = {h: {k: v for k, v in d.items() if k != "steps_table"} for h, d in per_head.items()}
    if protocol:
        numcalc_ref = protocol["numcalc_reference"]
        reference = numcalc_ref["reference"]
        figures["delta_qe_pp"] = round(numcalc_ref["original_gpu"]["qe_percent"] - reference["qe_percent"], 3)
        figures["delta_pe_deg"] = round(numcalc_ref["original_gpu"]["pe_deg"] - reference["pe_deg"], 3)
        print(f"paper protocol, NumCalc's original as reference and template (S {numcalc_ref['sensitivity_db']:.3f}): "
              f"QE {reference['qe_percent']:.3f} % / PE {reference['pe_deg']:.3f} deg; the GPU's original "
              f"{numcalc_ref['original_gpu']['qe_percent']:.3f} % / {numcalc_ref['original_gpu']['pe_deg']:.3f} deg")
        conditions = {}
        for head in sofa_gpu:
            if head == "original":
                continue
            by_numcalc = numcalc_ref[f"{head}_numcalc"]
            by_gpu = protocol["gpu_reference"][head]
            gpu_reference = protocol["gpu_reference"]["reference"]
            conditions[head] = {
                "numcalc_delta_qe_pp": round(by_numcalc["qe_percent"] - reference["qe_percent"], 3),
                "numcalc_delta_pe_deg": round(by_numcalc["pe_deg"] - reference["pe_deg"], 3),
                "gpu_delta_qe_pp": round(by_gpu["qe_percent"] - gpu_reference["qe_percent"], 3),
                "gpu_delta_pe_deg": round(by_gpu["pe_deg"] - gpu_reference["pe_deg"], 3)}
            print(f"{head} vs original, every head by one solver: NumCalc ΔQE {conditions[head]['numcalc_delta_qe_pp']:+.3f} pp"
                  f" / ΔPE {conditions[head]['numcalc_delta_pe_deg']:+.3f} deg; GPU ΔQE "
                  f"{conditions[head]['gpu_delta_qe_pp']:+.3f} pp / ΔPE {conditions[head]['gpu_delta_pe_deg']:+.3f} deg")
        figures["conditions_by_solver"] = conditions
    (results / "report.json").write_text(json.dumps({"figures": figures, "per_head": per_head,
                                                     "protocol": protocol}, indent=2, default=float))
    main_head = per_head.get("original") or next(iter(per_head.values()))
    main_phases = json.loads(str(np.load(results / f"{next(h for h in ('original', *solved) if h in per_head)}"
                                         "_pressures.npz")["phases_json"]))
    summary = {"gpu": figures["gpu"], "n_vertices": main_head["n_vertices"], "assembly": info.get("assembly", "arrays"),
               "assembly_seconds": round(float(np.median([p.get("assembly", 0.0) for p in main_phases])), 3),
               "lu_seconds": round(float(np.median([p.get("lu", 0.0) for p in main_phases])), 3),
               "seconds_per_frequency": round(main_head["seconds_per_frequency"], 2),
               "seconds_per_head": round(main_head["seconds_per_head"], 1),
               "max_median_db": round(max(h["max_median_db"] for h in per_head.values()), 3),
               "max_p95_db": round(max(h["max_p95_db"] for h in per_head.values()), 3),
               "delta_qe_pp": figures.get("delta_qe_pp"), "delta_pe_deg": figures.get("delta_pe_deg"),
               "numcalc_cpu_hours": round(main_head["numcalc_cpu_hours"], 2),
               "twin_max_relative_difference": figures["twin_max_relative_difference"],
               "sphere_max_p95_db": max(v["p95_db"] for v in sphere_errors.values()),
               "sphere_numcalc_max_p95_db": (max(v["p95_db"] for v in figures["sphere_numcalc_error_db"].values())
                                             if "sphere_numcalc_error_db" in figures else None),
               "heads_solved": solved}
    return summary


def gpu_here() -> bool:
    try:
        import cupy  # noqa: PLC0415

        return cupy.cuda.runtime.getDeviceCount() > 0
    except Exception:  # noqa: BLE001 - no CuPy, no driver, no device
        return False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("stage", nargs="?", choices=["all", "prepare", "solve", "numcalc-sphere", "report"],
                        default="all")
    parser.add_argument("--numcalc", default=None, help="NumCalc binary for numcalc-sphere (default: PATH, .venv/bin)")
    parser.add_argument("--inputs", type=Path, default=ROOT / "results" / "gpu_solve_inputs")
    parser.add_argument("--out", type=Path, default=KEPT)
    parser.add_argument("--backend", choices=["cupy", "numpy"], default="cupy")
    parser.add_argument("--budget-s", type=float, default=420.0, help="stop starting new heads after this many seconds")
    parser.add_argument("--heads", default=",".join(HEADS))
    parser.add_argument("--assembly", choices=["fused", "arrays"], default="fused",
                        help="far pairs by the fused CUDA kernel (mesh2hrtf_io/bem_fused.py; the array code where it "
                             "misses the CPU twin) or by the array code")
    args = parser.parse_args()
    heads = [h for h in args.heads.split(",") if h]
    if args.stage in ("all", "solve") and args.backend == "cupy" and not gpu_here():
        print("gpu_solve: no CUDA GPU here (CuPy finds none); results of the last GPU run are in "
              f"{KEPT.relative_to(ROOT)}; `benchmarks/gpu_solve.py report` prints them")
        raise SystemExit(2)
    if args.stage in ("all", "prepare"):
        prepare(args.inputs, heads)
    if args.stage in ("all", "solve"):
        solve(args.inputs, args.out, args.backend, args.budget_s, heads, args.assembly)
    if args.stage == "numcalc-sphere":
        numcalc_sphere(args.inputs, args.out, args.numcalc)
    if args.stage in ("all", "report"):
        print(json.dumps(report(args.inputs, args.out)))


if __name__ == "__main__":
    main()
