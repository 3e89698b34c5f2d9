"""The NumCalc solve plan printed before a run: steps stored vs to solve, and solver hours estimated from the
committed step store (evaluation/sonicom/steps), whose heads took 1.8-3.9 CPU hours each."""
import re
import shutil

import numpy as np

import trimesh

from mesh2hrtf_io.step_store import project_fingerprint, save_head
from reporting.solve_plan import measured_step_seconds, plan_rows, plan_text

from conftest import ROOT

STORE = ROOT / "evaluation" / "sonicom" / "steps"


def test_plan_counts_stored_steps_and_estimates_the_rest_from_the_committed_store(tmp_path):
    measured = measured_step_seconds(STORE)
    assert set(measured) == set(range(1, 41))  # every step of the 40-frequency set has been solved somewhere
    # NumCalc iterates longest at the lowest frequencies and has the most work at the highest: both ends cost more
    # than the middle of the set
    middle = sorted(measured[s] for s in range(10, 31))[10]
    assert measured[1] > 2 * middle and measured[40] > 2 * middle
    # a store holding 40 steps of a PPM head it does not keep (the committed steps of P143's unchanged head, copied
    # without a head.ply): a rebuild is not the same mesh, so none of them counts
    store = tmp_path / "steps"
    shutil.copytree(STORE / "P143" / "original" / "source_1", store / "S_old" / "ppm" / "source_1")
    copied = measured_step_seconds(store)
    rows = plan_rows(store, [("S_old", "ppm"), ("S_new", "ppm")], 40, [1])
    stored, new = rows
    assert (stored["stored"], stored["usable"], stored["to_solve"], stored["unknown_head"]) == (40, 0, 40, True)
    assert (new["stored"], new["to_solve"]) == (0, 40)
    assert 2.0 < new["solver_hours"] < 8.0
    assert abs(new["solver_hours"] - sum(copied.values()) / 3600.0) < 1e-9
    text = plan_text(rows, cores=2)
    assert "S_new ppm: 40 of 40 steps to solve (0 stored)" in text
    assert "S_old ppm: 40 of 40 steps to solve (40 stored for a head the store does not keep" in text
    assert f"~{(stored['solver_hours'] + new['solver_hours']) / 2:.1f} h on 2 core(s)" in text


def test_plan_without_a_store_gives_no_estimate(tmp_path):
    rows = plan_rows(None, [("S1", "ppm")], 40, [1, 2])
    assert rows[0]["to_solve"] == 80 and rows[0]["solver_hours"] is None
    assert "no stored steps to estimate" in plan_text(rows, cores=2)
    assert measured_step_seconds(tmp_path / "missing") == {}


def _project(folder, mesh_text: str):
    """The files a project's fingerprint hashes (meshes, grid, NC.inp), with made-up content."""
    (folder / "ObjectMeshes" / "Reference").mkdir(parents=True)
    (folder / "ObjectMeshes" / "Reference" / "Nodes.txt").write_text(mesh_text)
    (folder / "ObjectMeshes" / "Reference" / "Elements.txt").write_text("1\n")
    (folder / "EvaluationGrids" / "Sofa").mkdir(parents=True)
    (folder / "EvaluationGrids" / "Sofa" / "Nodes.txt").write_text("1 0 0 1\n")
    (folder / "NumCalc" / "source_1").mkdir(parents=True)
    (folder / "NumCalc" / "source_1" / "NC.inp").write_text("##\n")
    return folder


def _store_step(store, step: int, fingerprint: str, saved_utc: str | None):
    folder = store / "S1" / "ppm" / "source_1"
    folder.mkdir(parents=True, exist_ok=True)
    extra = {"saved_utc": saved_utc} if saved_utc is not None else {}
    np.savez(folder / f"step_{step:03d}.npz", pressure=np.zeros(1, complex), node_ids=np.ones(1, int),
             frequency_hz=100.0 * step, fingerprint=fingerprint, status_json="{}", **extra)


def test_steps_stored_for_an_earlier_head_count_as_to_solve(tmp_path):
    """A head re-solved after a change (e.g. the ear source moved): steps 1-6 of the old head, 1-2 of the new."""
    trimesh.creation.icosphere(subdivisions=1).export(tmp_path / "new_head.ply")
    new_head = _project(tmp_path / "new", "1 0 0 0\n")
    old_head = _project(tmp_path / "old", "1 0 0 0.001\n")
    store = tmp_path / "store"
    for step in range(1, 7):
        _store_step(store, step, project_fingerprint(old_head, 1), None)
    for step in (1, 2):  # the new head's steps overwrite the old ones
        _store_step(store, step, project_fingerprint(new_head, 1), "2026-12-01T10:00:00Z")
    checked = plan_rows(store, [("S1", "ppm")], 8, [1], {("S1", "ppm"): new_head})[0]
    assert (checked["stored"], checked["usable"], checked["stale"], checked["to_solve"]) == (6, 2, 4, 6)
    assert checked["checked"]
    text = plan_text([checked], cores=2)
    assert "6 of 8 steps to solve (2 stored for this head; 4 stored for an earlier head, solved again)" in text
    # before the export, with no head kept: a built head is rebuilt, so none of its steps counts
    unkept = plan_rows(store, [("S1", "ppm")], 8, [1], {("S1", "ppm"): tmp_path / "not_exported"})[0]
    assert (unkept["usable"], unkept["stale"], unkept["unknown_head"]) == (0, 6, True)
    # with the head kept (or for the dataset's own head), the most recently saved steps are taken for the head's
    save_head(tmp_path / "new_head.ply", store / "S1" / "ppm")
    guessed = plan_rows(store, [("S1", "ppm")], 8, [1], {("S1", "ppm"): tmp_path / "not_exported"})[0]
    assert (guessed["usable"], guessed["stale"], guessed["checked"]) == (2, 4, False)
    assert "not yet checked against the rebuilt head" in plan_text([guessed], cores=2)
    # the old head rebuilt: its 4 remaining steps are restorable, the new head's 2 are not
    back = plan_rows(store, [("S1", "ppm")], 8, [1], {("S1", "ppm"): old_head})[0]
    assert (back["usable"], back["to_solve"]) == (4, 4)


def test_the_embedded_plan_predicts_each_known_head_on_its_backend(sonicom):
    """With hrtf.solver embedded the run prints each head's predicted time on the configured backend: P143's dataset
    head (15,735 vertices) ~5.7 s per frequency on the GPU model (measured 5.71 s on an H200), minutes per frequency
    on the 2-core CPU model; a head built during the run is estimated after its export."""
    from reporting.solve_plan import embedded_plan_text

    heads = [("P143", "original", str(sonicom / "P143" / "head_graded_left.ply")), ("P143", "ppm", None)]
    gpu = embedded_plan_text(heads, "cuda", 40)
    assert "15735 vertices" in gpu and "after its export" in gpu
    seconds = float(re.search(r"~([0-9.]+) s per frequency", gpu).group(1))
    assert 4.5 < seconds < 7.0
    cpu = embedded_plan_text(heads, "auto", 40)
    assert float(re.search(r"~([0-9.]+) s per frequency", cpu).group(1)) > 100 * seconds
