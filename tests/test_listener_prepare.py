"""listener.prepare: a head scan as a user has it (STL, centimetres, turned, open at the neck) comes out closed, in
the project frame, with both pinnae cut out; a scan missing part of the head is refused and nothing is written."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from listener import ListenerError
from listener.prepare import OUTPUTS, main, prepare_head
from mesh2hrtf_io.ear_canal import ear_canal_centre


@pytest.fixture(scope="module")
def p143(p143_both_ears) -> trimesh.Trimesh:
    return p143_both_ears


def _scan(head: trimesh.Trimesh, path, keep=None, unit_mm: float = 10.0) -> None:
    """``head`` turned and moved, in units of ``unit_mm``, with only the faces ``keep``, written to ``path``."""
    faces = head.faces if keep is None else head.faces[keep]
    rotation = Rotation.random(random_state=4).as_matrix()
    vertices = (np.asarray(head.vertices) @ rotation.T + np.array([120.0, -40.0, 300.0])) / unit_mm
    trimesh.Trimesh(vertices, faces, process=False).export(path)


def test_a_turned_open_stl_in_cm_is_prepared(p143, tmp_path):
    scan = tmp_path / "scan.stl"
    _scan(p143, scan, keep=p143.triangles_center[:, 2] > -100.0)  # the neck cut open
    summary = prepare_head(scan, tmp_path / "prepared")
    assert summary["unit"] == "cm" and summary["repairs"]
    head = trimesh.load(tmp_path / "prepared" / "head.ply", process=False)
    assert head.is_watertight and head.is_winding_consistent and head.volume > 0
    # the canals the export will place its sources on lie on the y axis, 70-72 mm out
    for side, sign in (("left", 1.0), ("right", -1.0)):
        centre = ear_canal_centre(head, side)
        assert np.abs(centre[[0, 2]]).max() < 1.0
        assert 69.0 < sign * centre[1] < 73.0
        crop = trimesh.load(tmp_path / "prepared" / f"pinna_{side}_crop.ply", process=False)
        assert 6000 < len(crop.vertices) < 15000  # the dataset's crops: 9-12k vertices
        assert sign * crop.vertices[:, 1].min() > 50.0 or sign * crop.vertices[:, 1].max() < -50.0
    written = json.loads((tmp_path / "prepared" / "frame.json").read_text())
    assert written["unit"] == "cm" and len(written["matrix"]) == 4


def test_a_scan_missing_part_of_the_head_is_refused_and_nothing_written(p143, tmp_path):
    scan = tmp_path / "top_missing.ply"
    _scan(p143, scan, keep=p143.triangles_center[:, 2] < 60.0, unit_mm=1.0)  # the skull above 60 mm cut away
    with pytest.raises(ListenerError, match="hole .* mm around"):
        prepare_head(scan, tmp_path / "prepared")
    assert not any((tmp_path / "prepared" / name).exists() for name in OUTPUTS)


def test_inches_and_missing_files_are_refused_by_the_command(p143, tmp_path, capsys):
    scan = tmp_path / "inches.ply"
    _scan(p143, scan, unit_mm=25.4)
    with pytest.raises(SystemExit) as exit_info:
        main([str(scan), str(tmp_path / "out")])
    assert exit_info.value.code == 2 and "inches" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([str(tmp_path / "missing.ply"), str(tmp_path / "out")])
    assert "no such mesh file" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_separate_ear_scan_registers_onto_the_head_s_ear(p143, sonicom):
    """P143's left pinna crop, turned at random and in cm, as a separate scan of the left ear: it lands where it is
    on the head (vertices within 1 mm, median 0.2 mm); another person's ear (P039's) is refused."""
    from listener.ear_scan import register_ear_scan
    from listener.ears import pinna_crop

    crop = pinna_crop(p143, "left")
    scan = trimesh.load(sonicom / "P143" / "pinna_left_crop.ply", process=False)
    rotation = Rotation.random(random_state=5).as_matrix()
    posed = trimesh.Trimesh((np.asarray(scan.vertices) @ rotation.T + [40.0, -70.0, 20.0]) / 10.0, scan.faces,
                            process=False)
    registered, summary = register_ear_scan(posed, crop, "left")
    assert summary["unit"] == "cm" and summary["share_within_1mm"] > 0.95
    error = np.linalg.norm(registered.vertices - scan.vertices, axis=1)
    assert np.median(error) < 0.2 and error.max() < 1.0
    other = trimesh.load(sonicom / "P039" / "pinna_left_crop.ply", process=False)
    with pytest.raises(ListenerError, match="does not register onto the head's left ear"):
        register_ear_scan(other, crop, "left", "P039's ear")


def test_an_ear_scan_in_the_head_scan_s_coordinates_is_placed_by_the_head_s_frame(p143, sonicom):
    """P143's left crop written in the head scan's coordinates (turned, moved, cm) lands exactly where it is on the
    head through the head's frame, without registration; the same scan 5 mm off, or in mm while the head is in cm,
    is refused with a message that names ear_scan_frame."""
    from listener.ear_scan import place_ear_scan
    from listener.ears import pinna_crop

    crop = pinna_crop(p143, "left")
    scan = trimesh.load(sonicom / "P143" / "pinna_left_crop.ply", process=False)
    rotation = Rotation.random(random_state=5).as_matrix()
    shift = np.array([40.0, -70.0, 20.0])
    to_frame = np.eye(4)  # the head's frame: head scan coordinates (cm) -> project frame (mm)
    to_frame[:3, :3] = 10.0 * rotation.T
    to_frame[:3, 3] = -rotation.T @ shift

    def in_head_coordinates(vertices_mm: np.ndarray, unit_mm: float = 10.0) -> trimesh.Trimesh:
        return trimesh.Trimesh((np.asarray(vertices_mm) @ rotation.T + shift) / unit_mm, scan.faces, process=False)

    placed, summary = place_ear_scan(in_head_coordinates(scan.vertices), to_frame, "cm", crop, "left")
    assert summary["placed_by"] == "head frame" and summary["unit"] == "cm" and summary["share_within_1mm"] > 0.95
    assert np.abs(placed.vertices - scan.vertices).max() < 1e-6
    with pytest.raises(ListenerError, match="ear_scan_frame"):
        place_ear_scan(in_head_coordinates(scan.vertices + [0.0, 0.0, 5.0]), to_frame, "cm", crop, "left")
    with pytest.raises(ListenerError, match="ear_scan_frame"):
        place_ear_scan(in_head_coordinates(scan.vertices, unit_mm=1.0), to_frame, "cm", crop, "left")
