"""The embedded solver's backends: probes in a child process that may die, the cached verdicts, the explicit-backend
error, the real probe of this CPU, and the array code (CPU twin of the GPU path) against the numba assembly."""
import json
import logging
import sys

import numpy as np
import pytest
import trimesh

from mesh2hrtf_io import backends, bem, bem_arrays, burton_miller
from mesh2hrtf_io.errors import Mesh2HrtfIoError

#: a probe program that does what pocl's compiler did on AMD Zen 4: print LLVM's complaint and abort the process
ABORTING_PROBE = [sys.executable, "-c", "import os, sys; sys.stderr.write('LLVM ERROR: Cannot select: "
                  "0x5581: i64 = fsqrt 0x5580\\n'); sys.stderr.flush(); os.abort()"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Verdicts cached in a folder of this test."""
    monkeypatch.setenv("PPM_HRTF_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / backends.CACHE_FILE


def counting_probe(tmp_path, ok=True):
    """A probe program that counts its runs in a file and answers ``ok``."""
    counter = tmp_path / "runs.txt"
    code = ("import json, sys, pathlib; c = pathlib.Path(sys.argv[1]); "
            "c.write_text(c.read_text() + 'x' if c.exists() else 'x'); "
            f"pathlib.Path(sys.argv[2]).write_text(json.dumps({{'ok': {ok}, 'reason': 'fake device works'}}))")
    return counter, [sys.executable, "-c", code, str(counter), "{out}"]


def test_a_probe_that_dies_by_a_signal_is_a_failed_probe_and_auto_falls_back_to_numba(cache, caplog):
    with caplog.at_level(logging.WARNING, logger="mesh2hrtf_io.backends"):
        choice = backends.choose_backend("auto", candidates=("opencl",), probe_command=ABORTING_PROBE)
    assert choice.backend == "numba"
    assert "SIGABRT" in choice.reason and "LLVM ERROR: Cannot select" in choice.reason
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "using numba instead" in warnings[0] and "fsqrt" in warnings[0]
    verdict = json.loads(cache.read_text())
    assert [v["ok"] for v in verdict.values()] == [False]


def test_an_explicit_backend_that_fails_its_probe_stops_with_the_setting_to_change(cache):
    with pytest.raises(Mesh2HrtfIoError) as error:
        backends.choose_backend("opencl", probe_command=ABORTING_PROBE)
    message = str(error.value)
    assert "SIGABRT" in message and "fsqrt" in message and "embedded_device: numba" in message
    # the failed verdict is cached: the next run says the same without probing again
    with pytest.raises(Mesh2HrtfIoError, match="SIGABRT"):
        backends.choose_backend("opencl", probe_command=[sys.executable, "-c", "raise SystemExit(0)"])


def test_verdicts_are_cached_per_machine_and_library_versions(cache, tmp_path, monkeypatch):
    counter, command = counting_probe(tmp_path)
    first = backends.probe("opencl", command=command)
    assert counter.read_text() == "x" and first.ok and not first.cached
    again = backends.probe("opencl", command=command)
    assert again.cached and counter.read_text() == "x"  # no second probe
    versions = backends.library_versions("opencl")
    monkeypatch.setattr(backends, "library_versions",
                        lambda backend: {**versions, "pocl-binary-distribution": "99.0"})
    backends.probe("opencl", command=command)
    assert counter.read_text() == "xx"  # a changed library version probes again
    assert len(json.loads(cache.read_text())) == 2


def test_a_probe_that_exits_non_zero_names_its_last_stderr_line(cache):
    verdict = backends.probe("cuda", command=[sys.executable, "-c",
                                              "import sys; print('chatter', file=sys.stderr); "
                                              "sys.exit('CUDA driver version is insufficient')"], use_cache=False)
    assert not verdict.ok and "status 1" in verdict.reason and "insufficient" in verdict.reason


def test_numba_needs_no_probe_and_auto_without_a_gpu_is_numba(cache, monkeypatch):
    monkeypatch.setattr(backends, "gpu_seen", lambda: False)
    assert backends.choose_backend("numba").backend == "numba"
    assert backends.choose_backend("auto").backend == "numba"
    assert not cache.exists()  # nothing was probed
    with pytest.raises(Mesh2HrtfIoError, match="one of auto"):
        backends.choose_backend("gpu")


@pytest.mark.slow
def test_the_real_opencl_probe_on_this_cpu():
    """The real probe in a child process (verdict cached in the user's cache folder, as in a run): whatever this CPU
    is, the verdict is a clear yes or no, and auto never dies with it."""
    verdict = backends.probe("opencl")
    assert verdict.reason
    if verdict.ok:
        assert verdict.details["max_relative_difference"] < backends.PROBE_TOLERANCE
        assert verdict.details["kernel_max_error"] < 1e-12
    choice = backends.choose_backend("auto", candidates=("opencl",))
    assert choice.backend == ("opencl" if verdict.ok else "numba")
    assert backends.probe("opencl").cached


def test_doctor_reports_every_backend_and_the_cached_verdicts(cache, tmp_path):
    from mesh2hrtf_io.doctor import embedded_status

    backends.probe("opencl", command=ABORTING_PROBE)
    status = embedded_status()
    assert status["usable"] and set(status["backends"]) == {"numba", "opencl", "cuda"}
    assert status["backends"]["numba"]["usable"]
    opencl = status["backends"]["opencl"]
    assert opencl["verdict"]["ok"] is False and "SIGABRT" in opencl["verdict"]["reason"]
    assert status["auto"] in ("numba", "cuda")


# --- the array code (bem_arrays.py): the GPU path's CPU twin ---------------------------------------------------

def demo_like_head():
    """A closed ellipsoid of demo-head size and resolution (1,250 vertices; the demo heads have ~1,190)."""
    sphere = trimesh.creation.uv_sphere(radius=1.0, count=[25, 25])
    head = trimesh.Trimesh(sphere.vertices * [0.095, 0.076, 0.115], sphere.faces)  # merged poles
    ears = [[int(np.argmin(np.linalg.norm(head.triangles_center - [0, side * 0.076, 0], axis=1)))] for side in (1, -1)]
    return head, ears


def surface_of(head):
    bempp = bem._bempp()
    grid = bempp.Grid(np.ascontiguousarray(head.vertices.T), np.ascontiguousarray(head.faces.T.astype(np.uint32)))
    p1 = bempp.function_space(grid, "P", 1)
    far = burton_miller.far_field_geometry(grid, p1, bem.REGULAR_QUADRATURE_ORDER)
    touching = burton_miller.singular_pairs(grid, p1, bem.SINGULAR_QUADRATURE_ORDER)
    return far, touching, bem_arrays.from_geometry(far, touching)


@pytest.mark.parametrize("frequency_hz", [16000.0])
def test_the_gpu_kernels_cpu_twin_equals_the_numba_assembly(frequency_hz, tmp_path):
    """The array assembly of i/k W - K (far pairs in chunks, touching pairs by quadrature group) run on NumPy equals
    the one-pass numba assembly to 1e-10 relative on a demo-sized head; the saved surface loads back the same."""
    head, _ = demo_like_head()
    far, touching, arrays = surface_of(head)
    arrays.save(tmp_path / "surface.npz")
    loaded = bem_arrays.SurfaceArrays.load(tmp_path / "surface.npz")
    dev = bem_arrays.DeviceSurface(loaded, bem_arrays.numpy_backend())
    k = 2 * np.pi * frequency_hz / 343.0
    coupling = 1j / k
    reference = burton_miller.assemble_far_pairs(far, k, coupling)
    burton_miller.add_singular_pairs(reference, touching, far, k, coupling)
    twin = bem_arrays.system_matrix(dev, k, coupling, with_mass=False, budget_bytes=50e6)
    assert np.abs(twin - reference).max() < 1e-10 * np.abs(reference).max()


def test_the_array_solve_equals_bempp_cl_operators_for_both_ears():
    """Right-hand sides and potentials of the array code (numba backend) equal bempp-cl's own operators (the
    opencl backend's path, here run by bempp-cl's numba kernels) to 1e-9 relative: both ears, 5 kHz."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.0875)
    ears = [[int(np.argmin(np.linalg.norm(sphere.triangles_center - [0, side * 0.0875, 0], axis=1)))]
            for side in (1, -1)]
    points = np.random.default_rng(1).normal(size=(40, 3))
    points = 1.2 * points / np.linalg.norm(points, axis=1, keepdims=True)
    bempp = bem._bempp()
    segments = np.zeros(len(sphere.faces), np.uint32)
    segments[ears[0]] = 1
    segments[ears[1]] = 2
    grid, p1, mass, far, touching, arrays = bem._surface(bempp, sphere.vertices, sphere.faces, segments)
    frequency, k = 5000.0, 2 * np.pi * 5000.0 / 343.0
    system = burton_miller.assemble_far_pairs(far, k, 1j / k)
    burton_miller.add_singular_pairs(system, touching, far, k, 1j / k)
    np.add.at(system, (mass[0], mass[1]), 0.5 * mass[2])
    reference = bem._opencl_sources(bempp, grid, p1, system.copy(), segments, [(ears[0], 0.1), (ears[1], 0.1)],
                                    points, frequency, k, 1j / k, 1.2)
    dev = bem_arrays.DeviceSurface(arrays, bem_arrays.numpy_backend())
    twin = bem_arrays.solve_sources_arrays(dev, [(np.array(ears[0]), 0.1), (np.array(ears[1]), 0.1)], points,
                                           frequency, 343.0, 1.2)
    for a, b in zip(reference, twin):
        assert np.abs(a - b).max() < 1e-9 * np.abs(a).max()


def test_gpu_tests_skip_cleanly_without_a_gpu():
    """Without CuPy and a GPU the cuda backend is never chosen by auto and its probe fails with a reason."""
    if backends.gpu_seen():
        pytest.skip("a GPU is here: benchmarks/gpu_solve.py measures it")
    assert "cuda" not in backends.auto_candidates()
    with pytest.raises(ImportError):
        bem_arrays.cupy_backend()


def test_the_workflow_stops_before_any_job_when_the_explicit_backend_failed_its_probe(tmp_path, monkeypatch):
    """hrtf.embedded_device: opencl with a failed verdict for this machine (cached, as a probe that died leaves it):
    the demo run stops at once, naming the failure and the setting; nothing is made."""
    import shutil
    import subprocess

    from conftest import ROOT

    cache_folder = tmp_path / "cache"
    monkeypatch.setenv("PPM_HRTF_CACHE_DIR", str(cache_folder))
    assert not backends.probe("opencl", command=ABORTING_PROBE).ok
    work = tmp_path / "project"
    for folder in ("workflow", "rules", "config"):
        shutil.copytree(ROOT / folder, work / folder)
    (work / "config" / "opencl.yaml").write_text("hrtf:\n  embedded_device: opencl\n")
    done = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "1", "--configfile",
                           str(work / "config" / "config.yaml"), str(work / "config" / "opencl.yaml")],
                          cwd=work, capture_output=True, text=True, timeout=300,
                          env={**__import__("os").environ, "PPM_HRTF_CACHE_DIR": str(cache_folder),
                               "PYTHONPATH": str(ROOT)})
    output = done.stdout + done.stderr
    assert done.returncode != 0
    assert "SIGABRT" in output and "embedded_device: numba" in output
    assert not (work / "results").exists()


def test_the_gpu_evaluation_config_refuses_a_machine_without_a_gpu_before_any_job(tmp_path, sonicom):
    """config/paper_sonicom_gpu.yaml (every head by the embedded solver on cuda): where the cuda probe fails (no
    CuPy or no GPU), even a dry run stops at once with the probe's reason and what to install or set."""
    import os
    import subprocess

    from conftest import ROOT

    if backends.gpu_seen():
        pytest.skip("a GPU is here")
    done = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--cores", "1", "--configfile",
                           "config/paper_sonicom.yaml", "config/paper_sonicom_gpu.yaml"], cwd=ROOT,
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PPM_HRTF_CACHE_DIR": str(tmp_path / "cache")})
    output = done.stdout + done.stderr
    assert done.returncode != 0
    assert "'cuda' failed its probe" in output and "pip install -e '.[gpu]'" in output


def test_a_head_too_large_for_the_gpu_is_refused_with_the_sizes():
    """The GPU memory check (before the first frequency): P143's 15,735-vertex head fits an 80 GB card with the full
    work budget; on a 16 GB card with 8 GB free it is refused, naming what it needs and the alternatives."""
    budget = bem_arrays.work_budget_for(15735, 79e9, 80e9)
    assert budget == bem_arrays.GPU_WORK_BUDGET_BYTES
    assert 2 * 16 * 15735**2 + budget < 79e9
    with pytest.raises(Mesh2HrtfIoError) as error:
        bem_arrays.work_budget_for(15735, 8e9, 16e9, source="P143 original")
    message = str(error.value)
    assert "P143 original" in message and "9.9 GB" in message and "8.0 of 16.0 GB" in message
    assert "NumCalc" in message and "coarser mesh" in message


def test_a_probe_child_may_not_dump_core(cache):
    """A probe that aborts must not write a core file (a driver's address space: minutes of system time): its
    core-file limit is 0 before it starts, and the probe module turns dumping off itself."""
    code = ("import json, resource, sys; soft, hard = resource.getrlimit(resource.RLIMIT_CORE); "
            "open(sys.argv[1], 'w').write(json.dumps({'ok': soft == 0 and hard == 0, 'reason': f'{soft} {hard}'}))")
    verdict = backends.probe("opencl", command=[sys.executable, "-c", code, "{out}"])
    assert verdict.ok, verdict.reason
    import subprocess

    # in this very process the call works and the flag reads back as off (PR_GET_DUMPABLE = 3)
    check = ("import ctypes; from mesh2hrtf_io.backends import no_core_dumps; no_core_dumps(); "
             "print(ctypes.CDLL(None).prctl(3, 0, 0, 0, 0))")
    if sys.platform.startswith("linux"):
        done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, check=True)
        assert done.stdout.strip() == "0"


def test_solve_takes_its_steps_before_or_after_the_project(tmp_path, capsys):
    """`m2h solve --steps 30 PROJECT` reads 30 as the step and PROJECT as the project (with nargs='*' the project
    was taken for a step: 'invalid int value')."""
    from mesh2hrtf_io.cli import main

    missing = tmp_path / "no_project"
    for argv in (["solve", "--steps", "30", str(missing)], ["solve", str(missing), "--steps", "1,2,30"]):
        assert main(argv) != 0
        assert "not a Mesh2HRTF project folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["solve", str(missing), "--steps", "0"])
    assert "numbered from 1" in capsys.readouterr().err


def test_the_fused_far_pair_kernel_equals_the_array_code_in_the_cuda_simulator(tmp_path):
    """The fused CUDA kernel (mesh2hrtf_io/bem_fused.py: one thread per element pair, its 3 x 3 block added straight
    into the matrix) run by numba's CUDA simulator equals the array code's far pairs to 1e-10 relative on a small
    sphere at 8 kHz; its touching rule (a shared vertex) picks exactly the singular rule's pairs."""
    import os
    import subprocess

    sphere = trimesh.creation.icosphere(subdivisions=1, radius=0.0875)
    _, _, arrays = surface_of(sphere)
    arrays.save(tmp_path / "surface.npz")
    shared = {(a, b) for a in range(arrays.n_elements) for b in range(arrays.n_elements)
              if set(arrays.dofs[a]) & set(arrays.dofs[b])}
    assert shared == set(zip(arrays.touch_test.tolist(), arrays.touch_trial.tolist()))
    code = ("import sys, numpy as np; from mesh2hrtf_io import bem_arrays; "
            "from mesh2hrtf_io.bem_fused import far_pairs_fused; "
            "dev = bem_arrays.DeviceSurface(bem_arrays.SurfaceArrays.load(sys.argv[1]), bem_arrays.numpy_backend()); "
            "k = 2 * np.pi * 8000.0 / 343.0; ref = bem_arrays.far_pairs(dev, k, 1j / k); "
            "fused = far_pairs_fused(dev, k, 1j / k); print(np.abs(fused - ref).max() / np.abs(ref).max())")
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "surface.npz")], capture_output=True, text=True,
                          env={**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout.strip().splitlines()[-1]) < 1e-10
