"""listener.head_frame: a real head scan in any pose and unit comes back to the project frame (interaural axis
through the ear canals, origin between them, nose ahead, skull up); scans without ears, in inches or with ears
too coarse are refused with the reason."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from listener import ListenerError, find_head_frame
from listener.dataset_heads import both_ears_head
from listener.head_frame import settings
from listener.units import infer_unit


def _posed(head: trimesh.Trimesh, seed: int, unit_mm: float) -> tuple[trimesh.Trimesh, np.ndarray]:
    """``head`` (mm) turned and moved at random and written in units of ``unit_mm``; the 4x4 applied (mm)."""
    rng = np.random.default_rng(seed)
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    pose[:3, 3] = rng.uniform(-300.0, 300.0, 3)
    vertices = (np.asarray(head.vertices) @ pose[:3, :3].T + pose[:3, 3]) / unit_mm
    return trimesh.Trimesh(vertices, head.faces, process=False), pose


def _not_kept() -> dict:
    config = settings()
    config["kept"] = {"origin_mm": -1.0, "axis_deg": 0.0, "pitch_deg": 0.0}
    return config


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


@pytest.fixture(scope="module")
def p143(p143_both_ears) -> trimesh.Trimesh:
    return p143_both_ears


@pytest.fixture(scope="module")
def p143_frame(p143):
    return find_head_frame(p143, "P143", _not_kept())


def test_the_frame_of_a_dataset_head_is_its_interaural_axis(p143_frame):
    """On SONICOM P143 in its own frame: the axis through the canal floors is within 1 deg of the dataset's y,
    the pitch within 2 deg of its x; the origin sits 6 mm from the dataset's (the canal floors lie 5 mm below
    the axis the dataset's creators chose: a convention, see data/head_frame.yaml)."""
    rotation, shift = p143_frame.matrix[:3, :3], p143_frame.matrix[:3, 3]
    assert _angle_deg(rotation[1], np.array([0.0, 1.0, 0.0])) < 1.0
    assert _angle_deg(rotation[0], np.array([1.0, 0.0, 0.0])) < 2.0
    origin = -rotation.T @ shift
    assert 3.0 < np.linalg.norm(origin) < 8.0
    # in the frame found, the canals lie on the y axis, left at +y, 70-72 mm out
    np.testing.assert_allclose(p143_frame.left_canal_mm[[0, 2]], 0.0, atol=1e-6)
    assert 69.0 < p143_frame.left_canal_mm[1] < 73.0 and -73.0 < p143_frame.right_canal_mm[1] < -69.0
    assert p143_frame.nose_tip_mm[0] > 100.0


@pytest.mark.parametrize("seed, unit", [(2, "m")])
def test_a_head_in_any_pose_and_unit_comes_back(p143, p143_frame, seed, unit):
    """The same head turned at random, moved by up to 300 mm and written in m (cm: the heads below): the frame
    found maps it
    where the unposed head's frame maps the head (axis within 2 deg, origin within 2 mm, pitch within 2 deg)."""
    scale = {"mm": 1.0, "cm": 10.0, "m": 1000.0}[unit]
    posed, pose = _posed(p143, seed, scale)
    frame = find_head_frame(posed, f"P143 posed {seed}", _not_kept())
    assert frame.unit == unit and not frame.kept
    # frame.matrix acts on the file's units; the composite file -> mm -> unposed mm is frame.matrix @ S @ pose^-1
    composite = frame.matrix @ np.diag([1.0 / scale] * 3 + [1.0]) @ pose
    reference = p143_frame.matrix
    for row in range(3):
        assert _angle_deg(composite[row, :3], reference[row, :3]) < 2.0
    points = np.asarray(p143.vertices[::500])
    moved = points @ composite[:3, :3].T + composite[:3, 3]
    expected = points @ reference[:3, :3].T + reference[:3, 3]
    assert np.linalg.norm(moved - expected, axis=1).max() < 4.0
    assert np.linalg.norm(frame.left_canal_mm - p143_frame.left_canal_mm) < 2.0


@pytest.mark.parametrize("subject, seed", [("P039", 21)])
def test_another_sonicom_head_comes_back_to_its_axis(sonicom, subject, seed):
    """P039 (whose deepest concha fill is the cymba, not the canal), turned at random and written in cm: the axis
    found is within 2 deg of the dataset's y, the pitch within 2 deg of its x, the origin within 8 mm of its origin
    (the dataset's own convention, above). P067 comes back as well (0.78 deg, the survey in
    docs/stages/head-frame.md); it is left out here for CI time."""
    head = both_ears_head(sonicom / subject)
    posed, pose = _posed(head, seed, 10.0)
    frame = find_head_frame(posed, f"{subject} posed")
    composite = frame.matrix @ np.diag([0.1, 0.1, 0.1, 1.0]) @ pose
    assert _angle_deg(composite[1, :3], np.array([0.0, 1.0, 0.0])) < 2.0
    assert _angle_deg(composite[0, :3], np.array([1.0, 0.0, 0.0])) < 2.0
    assert np.linalg.norm(composite[:3, 3]) < 8.0


def test_a_second_scanner_s_head_comes_back(sonicom):
    """CGTUB's head (2.5 mm edges, both ears; another dataset's frame): as given (already in a project frame) it is
    kept exactly as it is; turned at random and in cm, the axis comes back within 2 deg of that dataset's y and the
    origin within 2 mm of its origin."""
    head = trimesh.load(sonicom.parent / "heads" / "cgtub_head_2mm.ply", process=False, force="mesh")
    kept = find_head_frame(head, "CGTUB")
    assert kept.kept
    np.testing.assert_array_equal(kept.matrix, np.eye(4))
    np.testing.assert_array_equal(kept.apply(head).vertices, head.vertices)
    posed, pose = _posed(head, 11, 10.0)
    frame = find_head_frame(posed, "CGTUB posed")
    composite = frame.matrix @ np.diag([0.1, 0.1, 0.1, 1.0]) @ pose
    assert _angle_deg(composite[1, :3], np.array([0.0, 1.0, 0.0])) < 2.0
    assert _angle_deg(composite[0, :3], np.array([1.0, 0.0, 0.0])) < 4.0
    assert np.linalg.norm(composite[:3, 3]) < 2.0


def _without_ear(head: trimesh.Trimesh, centres: list[np.ndarray]) -> trimesh.Trimesh:
    """``head`` with the skin within 35 mm of each point cut away and the hole closed flat (an ear cut off)."""
    import pymeshlab

    keep = np.ones(len(head.faces), bool)
    for centre in centres:
        keep &= np.linalg.norm(head.triangles_center - centre, axis=1) > 35.0
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(head.vertices), np.asarray(head.faces[keep])))
    ms.meshing_remove_unreferenced_vertices()
    ms.meshing_close_holes(maxholesize=2000)
    mesh = ms.current_mesh()
    return trimesh.Trimesh(mesh.vertex_matrix(), mesh.face_matrix(), process=False)


def test_a_head_without_ears_is_refused(sonicom):
    head = trimesh.load(sonicom.parent / "heads" / "cgtub_head_2mm.ply", process=False, force="mesh")
    ears = [np.array([-2.0, 66.4, -0.8]), np.array([1.9, -66.5, 0.4])]
    posed, _ = _posed(_without_ear(head, ears), 5, 1.0)
    with pytest.raises(ListenerError, match="no ears found"):
        find_head_frame(posed, "earless head")
    one, _ = _posed(_without_ear(head, ears[:1]), 6, 1.0)
    with pytest.raises(ListenerError, match="only one ear found"):
        find_head_frame(one, "one-eared head")


def test_units_are_told_from_the_size_and_inches_are_refused(p143):
    vertices = np.asarray(p143.vertices)
    limits = tuple(settings()["units"]["head_diameter_mm"])
    assert infer_unit(vertices, limits) == "mm"
    assert infer_unit(vertices / 10.0, limits) == "cm"
    assert infer_unit(vertices / 1000.0, limits) == "m"
    with pytest.raises(ListenerError, match="inches"):
        infer_unit(vertices / 25.4, limits, "head.ply")
    with pytest.raises(ListenerError, match="no unit"):
        infer_unit(vertices / 3.0, limits, "head.ply")


def test_coarse_ears_and_bad_vertices_are_refused(sonicom):
    head = trimesh.load(sonicom.parent / "heads" / "mesh2hrtf_example_head_5mm.ply", process=False, force="mesh")
    with pytest.raises(ListenerError, match="mm edges; a pinna needs at most 3"):
        find_head_frame(head, "example head")
    broken = trimesh.Trimesh(np.where(np.arange(len(head.vertices))[:, None] == 7, np.nan, head.vertices),
                             head.faces, process=False)
    with pytest.raises(ListenerError, match="NaN"):
        find_head_frame(broken, "head with NaN")


def test_the_mid_sagittal_plane_is_found_even_where_mirror_icp_stops_short():
    """An egg-shaped head (mm) with two ear bumps, symmetric about a plane tilted 20 deg from y: with a single ICP
    round ICP alone stops 0.6 deg and 0.6 mm off; the polish brings the plane within 0.1 deg and 0.1 mm."""
    from listener.head_frame import symmetry_plane

    rng = np.random.default_rng(3)
    points = rng.normal(size=(40_000, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    points *= np.array([100.0, 75.0, 110.0])
    points[:, 0] += 0.0015 * points[:, 2] ** 2  # front and back differ, so the mirror is only about the y plane
    for side in (1.0, -1.0):  # pinnae: bumps 12 mm out at the ends of the interaural axis
        near = np.linalg.norm(points - np.array([0.0, side * 75.0, 0.0]), axis=1) < 20.0
        points[near, 1] += side * 12.0
    tilt = Rotation.from_euler("z", 20.0, degrees=True).as_matrix()
    points = points @ tilt.T + np.array([3.0, 5.0, -2.0])
    normal, offset, _ = symmetry_plane(points, {"points": 6000, "iterations": 1})
    truth = tilt @ np.array([0.0, 1.0, 0.0])
    assert np.degrees(np.arccos(min(1.0, abs(normal @ truth)))) < 0.1
    assert abs(abs(offset) - abs(truth @ np.array([3.0, 5.0, -2.0]))) < 0.1
