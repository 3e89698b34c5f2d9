"""Loading pinna meshes: units, side, NaN, empty and corrupt files; atomic writes."""
import numpy as np
import pytest
import trimesh

from ppm.errors import PpmError
from ppm.mesh_io import load_left_pinna, load_mesh, write_mesh


@pytest.fixture(scope="module")
def left_crop(sonicom):
    return sonicom / "P039" / "pinna_left_crop.ply"


def test_left_crop_loads_and_right_crop_mirrors(sonicom, left_crop):
    left = load_left_pinna(left_crop)
    assert left.vertices[:, 1].mean() > 50
    right = load_left_pinna(sonicom / "P039" / "pinna_right_crop.ply", side="right")
    assert right.vertices[:, 1].mean() > 50
    # mirrored faces keep the normals outward: the mean normal faces +y like a left ear
    assert (right.face_normals[:, 1] * right.area_faces).sum() > 0


def test_right_ear_passed_as_left_is_refused(sonicom):
    with pytest.raises(PpmError, match=r"RIGHT ear.*mirror it"):
        load_left_pinna(sonicom / "P039" / "pinna_right_crop.ply")


def test_left_ear_passed_as_right_is_refused(left_crop):
    with pytest.raises(PpmError, match=r"side='right' was given but the pinna lies at \+y"):
        load_left_pinna(left_crop, side="right")


def test_mirrored_without_face_flip_is_refused(tmp_path, sonicom):
    right = trimesh.load(sonicom / "P039" / "pinna_right_crop.ply", process=False)
    bad = trimesh.Trimesh(right.vertices * [1, -1, 1], right.faces, process=False)  # faces not flipped
    path = tmp_path / "mirrored_badly.ply"
    bad.export(path)
    with pytest.raises(PpmError, match=r"faces -y.*flip its faces"):
        load_left_pinna(path)


def test_metres_are_detected(tmp_path, left_crop):
    mesh = trimesh.load(left_crop, process=False)
    path = tmp_path / "in_metres.ply"
    trimesh.Trimesh(mesh.vertices / 1000.0, mesh.faces, process=False).export(path)
    with pytest.raises(PpmError, match=r"in metres: scale it by 1000"):
        load_left_pinna(path)


def test_nan_empty_corrupt_and_missing_files(tmp_path, left_crop):
    mesh = trimesh.load(left_crop, process=False)
    vertices = mesh.vertices.copy()
    vertices[10] = np.nan
    nan_path = tmp_path / "nan.ply"
    trimesh.Trimesh(vertices, mesh.faces, process=False).export(nan_path)
    with pytest.raises(PpmError, match=r"nan.ply: 1 vertices hold NaN"):
        load_mesh(nan_path)
    empty = tmp_path / "empty.ply"
    empty.write_bytes(b"")
    with pytest.raises(PpmError, match="empty.ply: the file is empty"):
        load_mesh(empty)
    corrupt = tmp_path / "corrupt.stl"
    corrupt.write_bytes(b"solid x\nthis is not an stl\n")
    with pytest.raises(PpmError, match="corrupt.stl"):
        load_mesh(corrupt)
    with pytest.raises(PpmError, match="no such mesh file"):
        load_mesh(tmp_path / "missing.ply")
    vtk = tmp_path / "mesh.vtk"
    vtk.write_text("# vtk DataFile Version 3.0\n")
    with pytest.raises(PpmError, match="unsupported mesh format"):
        load_mesh(vtk)


def test_write_mesh_keeps_vertex_order_and_leaves_no_temp(tmp_path, left_crop):
    mesh = trimesh.load(left_crop, process=False)
    for suffix in (".ply", ".stl", ".obj"):
        out = write_mesh(tmp_path / f"m{suffix}", mesh.vertices, mesh.faces)
        back = trimesh.load(out, process=False, force="mesh")
        if suffix != ".stl":  # STL stores triangles, not shared vertices
            np.testing.assert_allclose(back.vertices, mesh.vertices, atol=1e-5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.obj", "m.ply", "m.stl"]
    with pytest.raises(PpmError, match="NaN"):
        write_mesh(tmp_path / "bad.ply", np.full((3, 3), np.nan), np.array([[0, 1, 2]]))
    assert not (tmp_path / "bad.ply").exists()
