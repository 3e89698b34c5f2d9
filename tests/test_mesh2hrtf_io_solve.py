"""Solving and collecting Mesh2HRTF projects: results files, resumption, SOFA output (with the analytic
rigid sphere standing in for the solver where only the bookkeeping is tested), the embedded solver on a
whole project, the cost estimate, and bad input."""
from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest
import sofar
import trimesh

from amt_bridge import read_hrtf_set
from mesh2hrtf_io import Mesh2HrtfIoError, sphere_grid, write_project
from mesh2hrtf_io.analytic import rigid_sphere_hrtf
from mesh2hrtf_io.bem import free_field_reference
from mesh2hrtf_io.cli import frequency_list
from mesh2hrtf_io.cli import main as m2h_main
from mesh2hrtf_io.cost import project_cost
from mesh2hrtf_io.embedded import solve_project_embedded
from mesh2hrtf_io.numcalc import NumCalcError, find_numcalc, run_step
from mesh2hrtf_io.project_reader import read_project
from mesh2hrtf_io.results import missing_steps, read_eval_grid_pressure, step_folder, write_eval_grid_pressure
from mesh2hrtf_io.sofa_out import collect_sofa
from mesh2hrtf_io.ear_canal import ear_canal_elements

RADIUS_MM = 87.5
FREQUENCIES = frequency_list(250.0, 2000.0, 250.0)


def _sphere_project(folder, subdivisions=2, frequencies=FREQUENCIES, hrirs=True):
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=RADIUS_MM)
    ears = {side: ear_canal_elements(mesh, side) for side in ("left", "right")}
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=1, radius=1.2).vertices)
    write_project(folder, mesh.vertices, mesh.faces, ears, [grid], frequencies, speed_of_sound_m_s=343.0,
                  density_kg_m3=1.2, compute_hrirs=hrirs)
    return mesh, ears, grid


def _ear_direction(mesh, elements):
    centre = mesh.triangles_center[elements].mean(axis=0)
    return centre / np.linalg.norm(centre)


def _write_analytic_results(folder, mesh, ears, grid, steps=None):
    """NumCalc-format results from the analytic series (e^{-iωt}: conjugate), scaled like a solver's."""
    project = read_project(folder)
    for source, side in zip(project.sources, ("left", "right")):
        area = mesh.area_faces[ears[side]].sum() / 1e6
        for step, f in enumerate(project.frequencies_hz, start=1):
            if steps is not None and step not in steps:
                continue
            hrtf = np.conj(rigid_sphere_hrtf(f, RADIUS_MM / 1000, grid.points_m, _ear_direction(mesh, ears[side]), 343.0))
            pressure = hrtf * free_field_reference(grid.points_m, f, area, 343.0, 1.2)
            write_eval_grid_pressure(source.folder, step, grid.node_ids if hasattr(grid, "node_ids")
                                     else project.grids[0].node_ids, pressure)
    return project


def test_project_reads_back_as_written(tmp_path):
    mesh, ears, grid = _sphere_project(tmp_path / "p")
    project = read_project(tmp_path / "p")
    assert project.vertices_m.shape == (len(mesh.vertices), 3) and len(project.faces) == len(mesh.faces)
    np.testing.assert_allclose(project.vertices_m * 1000, mesh.vertices, atol=1e-3)
    assert [(s.ear, s.element_range) for s in project.sources] == [("left", (318, 318)), ("right", (319, 319))]
    np.testing.assert_allclose(project.evaluation_points_m, grid.points_m, atol=1e-6)
    np.testing.assert_array_equal(project.frequencies_hz, FREQUENCIES)


def test_results_files_detect_incomplete_steps(tmp_path):
    _sphere_project(tmp_path / "p")
    project = read_project(tmp_path / "p")
    source, ids = project.sources[0].folder, project.grids[0].node_ids
    write_eval_grid_pressure(source, 1, ids, np.ones(len(ids)) * (1 + 2j))
    np.testing.assert_allclose(read_eval_grid_pressure(source, 1, len(ids)), 1 + 2j)
    truncated = step_folder(source, 2) / "pEvalGrid"
    truncated.parent.mkdir(parents=True)
    truncated.write_text("\n".join((step_folder(source, 1) / "pEvalGrid").read_text().split("\n")[:20]) + "\n")
    write_eval_grid_pressure(source, 3, ids, np.full(len(ids), np.nan + 0j))
    assert missing_steps(source, len(FREQUENCIES), len(ids)) == list(range(2, len(FREQUENCIES) + 1))
    with pytest.raises(Mesh2HrtfIoError, match="incomplete"):
        read_eval_grid_pressure(source, 2, len(ids))
    with pytest.raises(Mesh2HrtfIoError, match="did not converge"):
        read_eval_grid_pressure(source, 3, len(ids))


def test_collected_sofa_is_the_referenced_hrtf_and_causal_hrirs(tmp_path):
    mesh, ears, grid = _sphere_project(tmp_path / "p")
    project = _write_analytic_results(tmp_path / "p", mesh, ears, grid)
    files = collect_sofa(tmp_path / "p")
    assert [f.name for f in files] == ["HRTF_Sphere.sofa", "HRIR_Sphere.sofa"]
    hrtf = sofar.read_sofa(str(files[0]), verify=True)
    assert hrtf.GLOBAL_SOFAConventions == "SimpleFreeFieldHRTF"
    data = hrtf.Data_Real + 1j * hrtf.Data_Imag
    assert data.shape == (len(grid.points_m), 2, len(FREQUENCIES))
    for index, side in enumerate(("left", "right")):
        expected = np.conj(np.stack([rigid_sphere_hrtf(f, RADIUS_MM / 1000, grid.points_m,
                                                       _ear_direction(mesh, ears[side]), 343.0) for f in FREQUENCIES],
                                    axis=-1))
        np.testing.assert_allclose(data[:, index], expected, atol=1e-4)  # grid nodes are stored to 1 µm
    np.testing.assert_allclose(hrtf.SourcePosition[:, 2], 1.2, atol=1e-6)
    np.testing.assert_allclose(np.asarray(hrtf.ReceiverPosition).reshape(2, 3)[:, 1], [RADIUS_MM / 1000, -RADIUS_MM / 1000], atol=3e-3)
    hrir = sofar.read_sofa(str(files[1]), verify=True)
    assert hrir.GLOBAL_SOFAConventions == "SimpleFreeFieldHRIR" and hrir.Data_SamplingRate == 4000.0
    # a source on the left reaches the left ear first (phase convention and ear order right)
    left_source = int(np.argmax(grid.points_m[:, 1]))
    onset = np.argmax(np.abs(hrir.Data_IR[left_source]) > 0.5 * np.abs(hrir.Data_IR[left_source]).max(), axis=-1)
    assert onset[0] <= onset[1]
    energy = (hrir.Data_IR[left_source] ** 2).sum(axis=-1)
    assert energy[0] > energy[1]
    as_read = read_hrtf_set(files[0])  # the localisation model reads our HRTF files in their convention
    assert (as_read.irs[left_source, 0] ** 2).sum() > (as_read.irs[left_source, 1] ** 2).sum()


def test_collection_refuses_partial_results(tmp_path):
    mesh, ears, grid = _sphere_project(tmp_path / "p")
    _write_analytic_results(tmp_path / "p", mesh, ears, grid, steps={1, 2, 3})
    with pytest.raises(Mesh2HrtfIoError, match=r"steps \[4, 5, 6, 7, 8\] are not solved"):
        collect_sofa(tmp_path / "p")
    assert not (tmp_path / "p" / "Output2HRTF").exists() or not list((tmp_path / "p" / "Output2HRTF").iterdir())


def test_embedded_solver_solves_a_project_and_resumes(tmp_path, caplog):
    """Whole project with the embedded solver (162-vertex sphere, 2 steps, both ears): within 1 dB of
    the series; a rerun solves nothing; a deleted step is solved again."""
    frequencies = [250.0, 500.0]
    mesh, ears, grid = _sphere_project(tmp_path / "p", frequencies=frequencies, hrirs=False)
    summary = solve_project_embedded(tmp_path / "p")
    assert summary["steps_solved"] == 4
    hrtf = sofar.read_sofa(str(collect_sofa(tmp_path / "p")[0]), verify=True)
    data = hrtf.Data_Real + 1j * hrtf.Data_Imag
    for index, side in enumerate(("left", "right")):
        for k, f in enumerate(frequencies):
            analytic = rigid_sphere_hrtf(f, RADIUS_MM / 1000, grid.points_m, _ear_direction(mesh, ears[side]), 343.0)
            assert np.abs(20 * np.log10(np.abs(data[:, index, k] / analytic))).max() < 1.0
    # which solver made the file is in its metadata
    assert hrtf.GLOBAL_NumericalSolver == f"embedded ({summary['backend']})" and summary["backend"] == "numba"
    assert "solved by" in hrtf.GLOBAL_Comment or "by embedded" in hrtf.GLOBAL_Comment
    assert solve_project_embedded(tmp_path / "p")["steps_solved"] == 0
    (step_folder(tmp_path / "p" / "NumCalc" / "source_2", 2) / "pEvalGrid").unlink()
    assert solve_project_embedded(tmp_path / "p")["steps_solved"] == 1


def test_cost_estimate_and_cli(tmp_path, capsys, monkeypatch):
    _sphere_project(tmp_path / "p")
    cost = project_cost(tmp_path / "p", "embedded")
    assert cost.n_sources == 2 and cost.n_frequencies == len(FREQUENCIES) and cost.n_elements == 320
    assert 0 < cost.cpu_hours < 1 and 0 < cost.peak_memory_gb < 1
    # on a GPU (model measured on an H200): one assembly and LU per frequency for both ears, GPU memory
    gpu = project_cost(tmp_path / "p", "embedded", device="cuda")
    assert gpu.solver == "embedded (cuda)" and gpu.cpu_hours < cost.cpu_hours and "H200" in gpu.time_source
    from mesh2hrtf_io.bem import estimate_cost
    head = estimate_cost(15735, 31466, 793, backend="cuda")  # P143's head: 5.7 s per frequency measured
    assert 4.5 < head.seconds_per_frequency < 7.0
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setattr("mesh2hrtf_io.numcalc.venv_numcalc", lambda: tmp_path / "nowhere" / "NumCalc")
    numcalc_cost = project_cost(tmp_path / "p", "numcalc")
    assert numcalc_cost.cpu_hours > 0 and np.isnan(numcalc_cost.peak_memory_gb)
    assert "rule of thumb" in numcalc_cost.time_source
    # with NumCalc (a stand-in answering -estimate_ram with 0.5 GB per step): near-field pairs + memory
    fake = tmp_path / "NumCalc"
    fake.write_text("#!/bin/sh\nfor k in 1 2 3 4 5 6 7 8; do echo \"$k $((k * 250)) 0.5\"; done > Memory.txt\n")
    fake.chmod(0o755)
    from mesh2hrtf_io.numcalc_cost import near_field_pairs, step_seconds, tree_of_project

    with_numcalc = project_cost(tmp_path / "p", "numcalc", str(fake))
    project = read_project(tmp_path / "p")
    tree = tree_of_project(project.vertices_m, project.faces, project.sources[0].folder / "NC.inp")
    pairs = near_field_pairs(project.vertices_m, project.faces, tree.finest_m)
    assert 320 < pairs <= 320**2
    assert with_numcalc.memory_source == "NumCalc -estimate_ram" and with_numcalc.peak_memory_gb == 0.5
    assert with_numcalc.cpu_hours == pytest.approx(round(2 * 8 * step_seconds(pairs, 0.5) / 3600, 3), abs=1e-3)
    assert m2h_main(["cost", str(tmp_path / "p")]) == 0
    assert json.loads(capsys.readouterr().out)["n_frequencies"] == len(FREQUENCIES)
    head = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS_MM)
    head.export(tmp_path / "head.ply")
    assert m2h_main(["export", str(tmp_path / "head.ply"), str(tmp_path / "q"), "--fmax", "1000", "--fstep", "500"]) == 0
    assert read_project(tmp_path / "q").frequencies_hz.tolist() == [500.0, 1000.0]
    (head.copy().apply_scale(0.001)).export(tmp_path / "head_m.ply")
    assert m2h_main(["export", str(tmp_path / "head_m.ply"), str(tmp_path / "r")]) == 2
    assert "millimetres" in capsys.readouterr().err


def test_missing_or_crashing_numcalc_is_a_clear_error(tmp_path, monkeypatch):
    import mesh2hrtf_io.numcalc as numcalc_module

    monkeypatch.setenv("PATH", str(tmp_path))
    # as on a machine where scripts/install_numcalc.sh never ran (this one may have NumCalc in .venv/bin)
    monkeypatch.setattr(numcalc_module, "venv_numcalc", lambda: tmp_path / "venv" / "bin" / "NumCalc")
    with pytest.raises(NumCalcError, match="not on PATH"):
        find_numcalc()
    with pytest.raises(NumCalcError, match="not found or not executable"):
        find_numcalc(tmp_path / "NumCalc")
    crashing = tmp_path / "NumCalc"
    crashing.write_text("#!/bin/sh\necho 'segmentation fault' >&2\nexit 139\n")
    crashing.chmod(crashing.stat().st_mode | stat.S_IXUSR)
    _sphere_project(tmp_path / "p")
    source = tmp_path / "p" / "NumCalc" / "source_1"
    with pytest.raises(NumCalcError, match="step 1 failed \\(exit 139"):
        run_step(find_numcalc(crashing), source, 1, 42)
    assert not (step_folder(source, 1) / "status.json").exists()


def test_a_step_that_diverges_with_the_tuned_cluster_tree_is_solved_with_numcalcs_own(tmp_path):
    """A stand-in NumCalc (the real one diverges only on a full graded head at 24 kHz, an hour per attempt) that
    fails to converge whenever NC.inp sets a level-0 cluster size: the runner's second attempt asks for NumCalc's
    own tree in a sibling folder and takes its result; a later run does not repeat attempts a status records."""
    import sys
    from pathlib import Path

    from mesh2hrtf_io.numcalc import DEFAULT_TREE

    _sphere_project(tmp_path / "p", frequencies=[1000.0])
    source = tmp_path / "p" / "NumCalc" / "source_1"
    nc_inp = (source / "NC.inp").read_text()
    (source / "NC.inp").write_text(nc_inp.replace("0 0 0 0.0000e+00 0 0 0", "0 0 0 3.4200e-02 0 0 0"))
    assert "3.4200e-02" in (source / "NC.inp").read_text()
    calls = tmp_path / "calls.txt"
    fake = tmp_path / "NumCalc"
    fake.write_text(f"""#!{sys.executable}
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, {str(Path(__file__).resolve().parents[1])!r})
from mesh2hrtf_io.results import write_eval_grid_pressure
step, limit = int(sys.argv[2]), sys.argv[6]
tuned = "3.4200e-02" in Path("NC.inp").read_text()
with open({str(calls)!r}, "a") as calls:
    calls.write(f"{{Path.cwd().name}} {{limit}}\\n")
write_eval_grid_pressure(".", step, np.arange(162), np.full(162, 1.0 + 0.5j))
log = "Warning: Maximum number of iterations is reached!" if tuned else "done"
Path(f"NC{{step}}-{{step}}.out").write_text(log + "\\n")
print("CGS: err_ori = 1.0")
print(f"{{limit}} {{0.9 if tuned else 5e-10}}")
""")
    fake.chmod(0o755)
    status = run_step(fake, source, 1, 162, max_iterations=30)
    assert status["converged"] and [a["cluster_tree"] for a in status["attempts"]] == ["project", DEFAULT_TREE]
    assert status["attempts"][0]["relative_residual"] == 0.9 and status["attempts"][1]["max_iterations"] == 60
    assert calls.read_text().split("\n")[:2] == ["source_1 30", f"{DEFAULT_TREE}_source_1 60"]
    assert (source / "NC1-1.out").read_text() == "done\n" and not (source.parent / f"{DEFAULT_TREE}_source_1").exists()
    # a scratch folder left beside the sources (an interrupted attempt) is not read as a source
    (source.parent / "source_1.old").mkdir()
    assert [s.folder.name for s in read_project(tmp_path / "p").sources] == ["source_1", "source_2"]
    assert read_eval_grid_pressure(source, 1, 162)[0] == 1.0 + 0.5j
    # a step whose recorded attempts all failed is not tried again with the same tree and limit
    failed = {"step": 1, "converged": False, "problems": ["not converged (maximum number of iterations reached)"],
              "attempts": [{"max_iterations": 30, "seconds": 1.0, "problems": ["not converged"]},
                           {"max_iterations": 60, "seconds": 1.0, "problems": ["not converged"]}]}
    (step_folder(source, 1) / "status.json").write_text(json.dumps(failed))
    calls.write_text("")
    status = run_step(fake, source, 1, 162, max_iterations=30)
    assert status["converged"] and calls.read_text() == f"{DEFAULT_TREE}_source_1 60\n"
    assert len(status["attempts"]) == 3
    # the failed first attempt is on record before the second starts: a second attempt killed by the scheduler
    # (NumCalc's own tree needs more memory) is followed by the second attempt alone
    import shutil

    shutil.rmtree(step_folder(source, 1))
    calls.write_text("")
    fake.write_text(fake.read_text().replace('log = "Warning', 'import os\nif not tuned: os.kill(os.getpid(), 9)\nlog = "Warning'))
    with pytest.raises(NumCalcError, match="exit -9.*killed by SIGKILL, most often the out-of-memory killer"):
        run_step(fake, source, 1, 162, max_iterations=30)
    recorded = json.loads((step_folder(source, 1) / "status.json").read_text())
    assert not recorded["converged"] and [a["cluster_tree"] for a in recorded["attempts"]] == ["project"]


def test_where_numcalc_cgs_stopped_is_read_from_its_output():
    """NumCalc 1.2.4 prints "<iteration> <relative residual>" every 10 iterations and where CGS stops (after its
    "CGS: err_ori" line; absolute errors on lines of their own); a step stopped by the iteration limit at or below
    ACCEPTED_RESIDUAL is kept (studies/numcalc_residual.py: 1e-6 left the far field within 3e-5 dB), above it not."""
    from mesh2hrtf_io.numcalc import ACCEPTED_RESIDUAL, _close_enough, last_residual

    stdout = ("Assembling\n0 12\n\nCGS: err_ori = 0.0316\n10 0.183697\n10 Abs Error:0.0058\n20 2.74954e-07\n"
              "20 Abs Error:8.7e-09\n25 9.5e-08\n\nPost processing\n")
    assert last_residual(stdout) == (25, 9.5e-08)
    assert last_residual("Assembling\n0 12\n") is None  # no CGS output: nothing read from other numbers
    limit = "not converged (maximum number of iterations reached)"
    assert _close_enough({"problems": [limit], "relative_residual": ACCEPTED_RESIDUAL})
    assert not _close_enough({"problems": [limit], "relative_residual": 8.4e-6})
    assert not _close_enough({"problems": [limit]})  # residual not printed: rerun
    assert not _close_enough({"problems": [limit, "too many integral points"], "relative_residual": 1e-8})


def test_a_solve_depends_on_frequency_over_speed_of_sound_only(tmp_path):
    """A referenced HRTF solved at f with c equals the one solved at f * c' / c with c' (the Helmholtz problem and
    the free-field reference depend on k = 2 pi f / c alone): studies/speed_of_sound.py relabels committed
    solves this way instead of solving them again."""
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS_MM)
    ears = {"left": ear_canal_elements(mesh, "left")}
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=1, radius=1.2).vertices)
    spectra = {}
    for name, speed, frequencies in (("c343", 343.0, [1000.0, 2000.0]),
                                     ("c346", 346.18, [1000.0 * 346.18 / 343.0, 2000.0 * 346.18 / 343.0])):
        write_project(tmp_path / name, mesh.vertices, mesh.faces, ears, [grid], frequencies, source_type="Left ear",
                      speed_of_sound_m_s=speed, density_kg_m3=1.2, compute_hrirs=False)
        solve_project_embedded(tmp_path / name)
        hrtf = sofar.read_sofa(str(collect_sofa(tmp_path / name)[0]), verify=False)
        spectra[name] = hrtf.Data_Real + 1j * hrtf.Data_Imag
    np.testing.assert_allclose(spectra["c346"], spectra["c343"], rtol=1e-6, atol=1e-9)
    assert np.abs(np.diff(20 * np.log10(np.abs(spectra["c343"])), axis=-1)).max() > 0.5  # the two steps differ


def test_a_boundary_element_far_louder_than_the_source_is_reported_as_a_spike(tmp_path, capsys):
    """NumCalc's pBoundary of one step (element id, real, imaginary) with the source on elements 3-4 of NC.inp's
    BOUNDARY block: an element 22 dB above the source's loudest is a spike, one 3 dB below is not; a step without
    pBoundary (restored from the store) is not judged, nor is one the runner has not marked converged."""
    from mesh2hrtf_io.surface_spikes import source_elements, surface_spikes

    folder = tmp_path / "NumCalc" / "source_1"
    (folder / "be.out" / "be.1").mkdir(parents=True)
    (folder / "NC.inp").write_text("BOUNDARY\n## Left ear\nELEM 3 TO 4 VELO 0.1 -1 0.0 -1\nRETU\n")
    assert source_elements((folder / "NC.inp").read_text()).tolist() == [3, 4]
    levels_db = [-30.0, -18.0, 7.0, -15.0, -16.0, -40.0]  # element 2: +22 dB over the source's -15 dB
    rows = [f"    {i}  {10 ** (level / 20):.6E}  0.000000E+00" for i, level in enumerate(levels_db)]
    (folder / "be.out" / "be.1" / "pBoundary").write_text("Mesh2HRTF 1.2.4\n    2\n    0 6\n" + "\n".join(rows) + "\n")
    spikes = surface_spikes(folder, 1)
    assert spikes["elements"] == [2] and spikes["max_db_above_source"] == pytest.approx(22.0, abs=0.01)
    assert surface_spikes(folder, 1, margin_db=25.0)["elements"] == []
    assert surface_spikes(folder, 2) is None
    # the same for a whole project from the command line: only steps the runner marked converged are judged (a
    # step still running or being retried after a non-converged attempt has a pBoundary that is not final)
    from mesh2hrtf_io.cli import main

    (folder / "be.out" / "be.2").mkdir()
    (folder / "be.out" / "be.2" / "pBoundary").write_text((folder / "be.out" / "be.1" / "pBoundary").read_text())
    (folder / "be.out" / "be.2" / "status.json").write_text('{"step": 2, "converged": false}')
    assert main(["spikes", str(tmp_path)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["spiked_steps"] == 0 and report["unfinished"] == {"source_1": [1, 2]}
    (folder / "be.out" / "be.1" / "status.json").write_text('{"step": 1, "converged": true}')
    assert main(["spikes", str(tmp_path)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["spiked_steps"] == 1 and report["source_1"]["1"]["elements"] == [2]
    assert report["unfinished"] == {"source_1": [2]}
    assert main(["spikes", str(tmp_path / "NumCalc")]) == 2  # not a project: named
