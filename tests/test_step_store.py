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
from mesh2hrtf_io.step_store import project_fingerprint, restore_step, save_head, save_step, stored_head
from mesh2hrtf_io.ear_canal import ear_canal_elements

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


def test_a_built_head_is_kept_byte_for_byte_beside_its_steps(tmp_path):
    head = trimesh.creation.icosphere(subdivisions=2, radius=87.5)
    built = tmp_path / "results" / "head.ply"
    built.parent.mkdir()
    head.export(built)
    store = tmp_path / "store" / "S1" / "ppm"
    assert stored_head(store) is None and stored_head(None) is None
    kept = save_head(built, store)
    assert kept == stored_head(store) and kept.read_bytes() == built.read_bytes()
    # the built head's time, so that a workflow does not take the kept copy for an input newer than the project
    assert kept.stat().st_mtime == built.stat().st_mtime
    info = json.loads((store / "head.json").read_text())
    assert info["triangles"] == 320 and len(info["sha256"]) == 64
    assert save_head(kept, store) == kept  # exporting the kept head keeps it as it is
    # a rebuilt head that differs (another machine's rounding) replaces it: its steps are solved again
    trimesh.creation.icosphere(subdivisions=2, radius=87.6).export(built)
    save_head(built, store)
    assert kept.read_bytes() == built.read_bytes() and json.loads((store / "head.json").read_text())["sha256"] != info["sha256"]
    assert not list(store.glob(".*partial*"))


def test_exporting_with_a_head_store_keeps_the_head_and_its_steps_restore_on_a_fresh_export(tmp_path):
    from mesh2hrtf_io.hrtf_job import export_head_project

    built = tmp_path / "built" / "head.ply"
    built.parent.mkdir()
    trimesh.creation.icosphere(subdivisions=2, radius=87.5).export(built)
    settings = {"ears": "left", "frequencies_hz": {"list": FREQUENCIES}, "polar_step_deg": 30.0}
    store = tmp_path / "store"
    export_head_project(built, tmp_path / "first", settings, title="S1_ppm", head_store=store)
    project = read_project(tmp_path / "first")
    _solve_fake(project, 1, 1.0 + 0.5j)
    save_step(tmp_path / "first", 1, 1, store)
    # a fresh clone: no rebuilt head, the project exported from the stored one takes the stored step
    export_head_project(stored_head(store), tmp_path / "fresh", settings, title="S1_ppm", head_store=store)
    assert project_fingerprint(tmp_path / "fresh", 1) == project_fingerprint(tmp_path / "first", 1)
    assert restore_step(tmp_path / "fresh", 1, 1, store)
    # another speed of sound (config hrtf.speed_of_sound_m_s) is another solve: written, and never restored
    export_head_project(stored_head(store), tmp_path / "c343", {**settings, "speed_of_sound_m_s": 343.18},
                        title="S1_ppm", head_store=store)
    assert read_project(tmp_path / "c343").speed_of_sound_m_s == 343.18
    assert "\n343.18 1.1839e+00 " in (tmp_path / "c343" / "NumCalc" / "source_1" / "NC.inp").read_text()
    assert not restore_step(tmp_path / "c343", 1, 1, store)
