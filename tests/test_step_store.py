"""Solved steps stored outside the project and restored on a fresh export: only for the same project
(fingerprint), never over a changed mesh or setting; the NumCalc job function restores instead of solving."""
from __future__ import annotations

import json

import numpy as np
import trimesh

from mesh2hrtf_io import sphere_grid, write_project
from mesh2hrtf_io.hrtf_job import solve_numcalc_steps
from mesh2hrtf_io.project_reader import read_project
from mesh2hrtf_io.results import read_eval_grid_pressure, step_is_complete, write_eval_grid_pressure
from mesh2hrtf_io.step_store import project_fingerprint, restore_step, save_step
from stitching.ear_canal import ear_canal_elements

FREQUENCIES = [500.0, 1000.0, 2000.0]


def _export(folder, radius=87.5):
    head = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=1, radius=1.2).vertices)
    write_project(folder, head.vertices, head.faces, {"left": ear_canal_elements(head, "left")}, [grid], FREQUENCIES,
                  source_type="Left ear")
    return read_project(folder)


def _solve_fake(project, step, value):
    nodes = project.grids[0].node_ids
    write_eval_grid_pressure(project.sources[0].folder, step, nodes, np.full(len(nodes), value, complex))


def test_a_stored_step_comes_back_only_into_the_same_project(tmp_path):
    project = _export(tmp_path / "a")
    _solve_fake(project, 2, 0.5 - 0.25j)
    stored = save_step(tmp_path / "a", 1, 2, tmp_path / "store")
    assert stored.name == "step_002.npz" and stored.stat().st_size < 20000
    before = stored.read_bytes()
    save_step(tmp_path / "a", 1, 2, tmp_path / "store")
    assert stored.read_bytes() == before  # unchanged files do not churn in git

    again = _export(tmp_path / "fresh")  # a fresh clone exports the same project again
    assert project_fingerprint(tmp_path / "fresh", 1) == project_fingerprint(tmp_path / "a", 1)
    assert restore_step(tmp_path / "fresh", 1, 2, tmp_path / "store")
    np.testing.assert_allclose(read_eval_grid_pressure(again.sources[0].folder, 2), 0.5 - 0.25j)
    assert not restore_step(tmp_path / "fresh", 1, 3, tmp_path / "store")  # never solved

    _export(tmp_path / "changed", radius=88.0)  # another mesh: the stored result is not reused
    assert not restore_step(tmp_path / "changed", 1, 2, tmp_path / "store")
    assert not step_is_complete(tmp_path / "changed" / "NumCalc" / "source_1", 2, 42)


def test_the_numcalc_job_restores_stored_steps_without_numcalc(tmp_path, monkeypatch):
    project = _export(tmp_path / "a")
    for step in (1, 2, 3):
        _solve_fake(project, step, complex(step))
        save_step(tmp_path / "a", 1, step, tmp_path / "store")
    _export(tmp_path / "fresh")
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # no NumCalc anywhere: every step must be restored
    monkeypatch.setattr("mesh2hrtf_io.numcalc.venv_numcalc", lambda: tmp_path / "nowhere" / "NumCalc")
    solve_numcalc_steps(tmp_path / "fresh", 1, [1, 2, 3], tmp_path / "status.json", None, 250, store=tmp_path / "store")
    status = json.loads((tmp_path / "status.json").read_text())
    assert [s["restored_from"] for s in status["steps"]] == [str(tmp_path / "store")] * 3
    for step in (1, 2, 3):
        np.testing.assert_allclose(read_eval_grid_pressure(tmp_path / "fresh" / "NumCalc" / "source_1", step), step)
