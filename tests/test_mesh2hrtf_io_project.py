"""Mesh2HRTF 1.2.4 project export: exact layout and counts for a rigid sphere, round trips, bad input."""
import json

import numpy as np
import pytest
import trimesh

from mesh2hrtf_io import EvaluationGrid, Mesh2HrtfIoError, grid_from_sofa, sagittal_grid, write_project
from mesh2hrtf_io.project import read_counts
from mesh2hrtf_io.units import m_to_mm, mm_to_m

RADIUS_MM = 87.5


@pytest.fixture(scope="module")
def sphere():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS_MM)
    left = int(np.argmin(np.linalg.norm(mesh.triangles_center - [0, RADIUS_MM, 0], axis=1)))
    right = int(np.argmin(np.linalg.norm(mesh.triangles_center - [0, -RADIUS_MM, 0], axis=1)))
    return mesh, {"left": np.array([left]), "right": np.array([right])}


def test_mm_to_m_round_trip():
    values = np.array([[1.5, -87.5, 0.001]])
    np.testing.assert_array_equal(m_to_mm(mm_to_m(values)), values)


def test_sphere_project_has_the_exact_layout_and_counts(tmp_path, sphere, sonicom):
    mesh, ears = sphere
    sofa_grid = grid_from_sofa(sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa", name="SONICOM")
    planes = sagittal_grid(polar_step_deg=5.0)
    frequencies = np.arange(100.0, 1001.0, 100.0)
    folder = tmp_path / "sphere_project"
    layout = write_project(folder, mesh.vertices, mesh.faces, ears, [sofa_grid, planes], frequencies)

    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert files == ["EvaluationGrids/SONICOM/Elements.txt", "EvaluationGrids/SONICOM/Nodes.txt",
                     "EvaluationGrids/SagittalPlanes/Elements.txt", "EvaluationGrids/SagittalPlanes/Nodes.txt",
                     "NumCalc/source_1/NC.inp", "NumCalc/source_2/NC.inp",
                     "ObjectMeshes/Reference/Elements.txt", "ObjectMeshes/Reference/Nodes.txt", "numcalc_clusters.json",
                     "parameters.json"]
    assert not list(tmp_path.glob("*.partial"))

    n_nodes, node_lines = read_counts(folder / "ObjectMeshes/Reference/Nodes.txt")
    n_elements, element_lines = read_counts(folder / "ObjectMeshes/Reference/Elements.txt")
    assert (n_nodes, len(node_lines)) == (642, 642) and (n_elements, len(element_lines)) == (1280, 1280)
    nodes = np.array([line.split(" ") for line in node_lines], dtype=float)
    assert np.array_equal(nodes[:, 0], np.arange(642))
    np.testing.assert_allclose(m_to_mm(nodes[:, 1:]), mesh.vertices, atol=6e-4)  # 6 decimals in metres
    elements = np.array([line.split(" ") for line in element_lines], dtype=int)
    assert elements.shape[1] == 7 and np.array_equal(elements[:, 0], np.arange(1280))
    assert set(elements[:, 4]) == {0} and set(elements[:, 6]) == {0}
    # the ears are the last elements, as one-element ranges, and are the faces asked for
    assert layout.ear_ranges == {"left": (1278, 1278), "right": (1279, 1279)}
    assert sorted(elements[1278, 1:4]) == sorted(mesh.faces[ears["left"][0]])
    # outward normals survive the reordering: positive signed volume in metres
    assert trimesh.Trimesh(nodes[:, 1:], elements[:, 1:4], process=False).volume > 0

    grid_ids = []
    total_grid_nodes = total_grid_elements = 0
    for name, grid in (("SONICOM", sofa_grid), ("SagittalPlanes", planes)):
        count, lines = read_counts(folder / "EvaluationGrids" / name / "Nodes.txt")
        ids = [int(line.split(" ")[0]) for line in lines]
        assert count == len(grid.points_m) == len(lines)
        grid_ids += ids
        total_grid_nodes += count
        e_count, e_lines = read_counts(folder / "EvaluationGrids" / name / "Elements.txt")
        assert e_count == len(e_lines) and {line.split(" ")[4] for line in e_lines} == {"2"}
        assert {line.split(" ")[6] for line in e_lines} == {"1"}
        assert set(int(t) for line in e_lines for t in line.split(" ")[1:4]) <= set(ids)
        total_grid_elements += e_count
    assert len(set(grid_ids)) == len(grid_ids) and min(grid_ids) >= 200000
    assert total_grid_nodes == 793 + 3 * 72

    for source, (ear, label) in zip(("source_1", "source_2"), (("left", "Left ear"), ("right", "Right ear"))):
        raw = (folder / "NumCalc" / source / "NC.inp").read_bytes()
        assert b"\r" not in raw and b"\t" not in raw and raw.endswith(b"\n")
        text = raw.decode()
        lines = [line for line in text.split("\n") if line and not line.split(" ")[0].count("#")]
        assert lines[0] == "Mesh2HRTF 1.2.4"
        assert lines[3] == "1 10 0.000001 0.00e+00 1 0 0"
        assert lines[4] == "0 11" and lines[5] == "0.000000 0.000000e+00 0.0"
        assert lines[6] == "0.000001 0.010000e+04 0.0" and lines[15] == "0.000010 0.100000e+04 0.0"
        assert lines[16] == f"2 {1280 + total_grid_elements} {642 + total_grid_nodes} 0 0 2 1 4 0"
        first, last = layout.ear_ranges[ear]
        assert f"ELEM {first} TO {last} VELO 0.1 -1 0.0 -1" in text and f"## {label}" in text
        assert "NODES\n../../ObjectMeshes/Reference/Nodes.txt\n../../EvaluationGrids/SONICOM/Nodes.txt\n" in text
        assert not any("  " in line for line in text.split("\n") if not line.startswith("#"))
        assert text.rstrip("\n").endswith("END")

    parameters = json.loads((folder / "parameters.json").read_text())
    assert parameters["numSources"] == 2 and parameters["sourceType"] == "Both ears"
    assert parameters["frequencies"] == frequencies.tolist() and parameters["numFrequencies"] == 10
    assert parameters["evaluationGrids"] == ["SONICOM", "SagittalPlanes"]
    left_area = mesh.area_faces[ears["left"]].sum() / 1e6
    assert parameters["sourceArea"][0] == pytest.approx(left_area)
    assert parameters["sourceCenter"][0][1] == pytest.approx(RADIUS_MM / 1000, abs=0.002)


def test_single_ear_project(tmp_path, sphere):
    mesh, ears = sphere
    layout = write_project(tmp_path / "p", mesh.vertices, mesh.faces, {"right": ears["right"]},
                           [sagittal_grid()], [500.0, 1000.0], source_type="Right ear")
    assert layout.sources == ("source_1",)
    parameters = json.loads((tmp_path / "p" / "parameters.json").read_text())
    assert parameters["numSources"] == 1 and len(parameters["sourceCenter"]) == 3


def test_bad_input_is_refused_and_nothing_is_written(tmp_path, sphere):
    mesh, ears = sphere
    grids = [sagittal_grid()]
    cases = [
        ((mesh.vertices, mesh.faces[:-1], ears, grids, [100.0]), "open: 3 boundary edges"),
        ((mesh.vertices, mesh.faces[:, ::-1], ears, grids, [100.0]), "normals point inwards"),
        ((mesh.vertices / 1000, mesh.faces, ears, grids, [100.0]), "looks like metres"),
        ((mesh.vertices, mesh.faces, {"left": ears["left"]}, grids, [100.0]), "needs right ear elements"),
        ((mesh.vertices, mesh.faces, {"left": ears["left"], "right": ears["left"]}, grids, [100.0]),
         "same element is marked as left and right"),
        ((mesh.vertices, mesh.faces, ears, grids, [0.0, 100.0]), "above 0 Hz"),
        ((mesh.vertices, mesh.faces, ears, grids, [200.0, 100.0]), "strictly increasing"),
        ((mesh.vertices, mesh.faces, ears, [], [100.0]), "at least one evaluation grid"),
    ]
    for args, message in cases:
        with pytest.raises(Mesh2HrtfIoError, match=message):
            write_project(tmp_path / "bad", *args)
        assert not (tmp_path / "bad").exists() and not (tmp_path / "bad.partial").exists()


def test_grids_refuse_bad_points():
    with pytest.raises(Mesh2HrtfIoError, match="belong to no element"):
        EvaluationGrid("g", np.eye(3) + 1, np.zeros((0, 3), int))
    with pytest.raises(Mesh2HrtfIoError, match="lateral angles"):
        sagittal_grid(lateral_angles_deg=(95.0,))
    with pytest.raises(Mesh2HrtfIoError, match="plain folder name"):
        EvaluationGrid("my grid", np.eye(3), np.array([[0, 1, 2]]))


def test_a_full_grid_with_a_datasets_directions_holds_every_one_of_them_once(sonicom):
    """A listener's full grid plus SONICOM's 793 directions (config listener.dataset_grid): every dataset direction
    is on the grid (at its own 1.5 m), none twice, the full grid's own points first and unchanged."""
    from mesh2hrtf_io.grids import full_grid, grid_from_sofa, with_directions_of

    full = full_grid(10.0)
    dataset = grid_from_sofa(sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa", name="Dataset")
    merged = with_directions_of(full, dataset)
    assert np.array_equal(merged.points_m[:len(full.points_m)], full.points_m)
    unit = merged.points_m / np.linalg.norm(merged.points_m, axis=1, keepdims=True)
    wanted = dataset.points_m / np.linalg.norm(dataset.points_m, axis=1, keepdims=True)
    nearest = np.max(unit @ wanted.T, axis=0)
    assert len(dataset.points_m) == 793 and np.all(nearest > np.cos(np.radians(0.1)))
    assert len(np.unique(np.round(unit, 9), axis=0)) == len(unit)
    added = merged.points_m[len(full.points_m):]
    assert np.allclose(np.linalg.norm(added, axis=1), 1.5, atol=1e-6)
    assert with_directions_of(merged, dataset) is merged  # nothing left to add
