"""The template pinna: the packaged default and a (reduced) leave-one-subject-out build from real scans."""
import json
import shutil

import numpy as np
import pytest
import trimesh

from ppm.errors import PpmError
from ppm.landmarks import LANDMARKS_NAME, load_landmarks
from ppm.mesh_io import load_left_pinna
from ppm.template import default_template_dir, load_template
from ppm.template.build import build_template_folder, discover_scans
from ppm.template.segment import pinna_region


def test_packaged_template_is_one_clean_left_pinna_with_a_skin_ring():
    template = load_template()
    mesh = template.mesh
    assert len(mesh.split(only_watertight=False)) == 1
    assert mesh.is_winding_consistent
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    assert counts.max() == 2
    boundary = mesh.edges_sorted[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    assert len(trimesh.graph.connected_components(boundary)) == 1  # open only at the outer ring
    edges = mesh.edges_unique_length
    assert 0.9 < np.median(edges) < 1.1  # mm
    assert edges.max() < 2.5
    # project frame, left ear: lateral (+y), about 60-75 mm tall, 35-50 mm wide (pinna + skin ring)
    extent = np.ptp(mesh.vertices, axis=0)
    assert mesh.vertices[:, 1].mean() > 50
    assert 60 < extent[2] < 90 and 30 < extent[0] < 60
    # float32-representable, so Blender's rest pose is exactly the template
    assert np.array_equal(template.vertices_mm, template.vertices_mm.astype(np.float32).astype(np.float64))


def test_provenance_names_every_scan_and_the_licence():
    provenance = load_template().provenance
    assert len(provenance["scans"]) == 6
    assert {s["subject"] for s in provenance["scans"]} == {"P039", "P067", "P143"}
    assert all(len(s["sha256"]) == 64 for s in provenance["scans"])
    assert "MIT" in provenance["source_and_licence"]
    assert provenance["excluded_subjects"] == []


def test_provenance_hashes_match_the_shared_scans(sonicom):
    import hashlib

    for scan in load_template().provenance["scans"]:
        path = sonicom / scan["subject"] / scan["file"]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == scan["sha256"]


def test_template_is_close_to_every_scan(sonicom):
    """Every template point within the pinna lies near each scanned ear (the mean of the six)."""
    template = load_template().mesh
    for scan in discover_scans(sonicom):
        target = load_left_pinna(scan.path, scan.side)
        distance = trimesh.proximity.closest_point(target, template.vertices)[1]
        assert np.median(distance) < 2.0, scan.label  # mm
        assert np.percentile(distance, 95) < 5.5, scan.label


def test_landmarks_are_vertex_ids_on_named_anatomy():
    template = load_template()
    landmarks = load_landmarks(template)
    assert {"canal_entrance", "tragus_tip", "antitragus_tip", "helix_top", "lobule_bottom",
            "antihelix_fork", "cavum_conchae", "cymba_conchae"} <= set(landmarks)
    v = template.vertices_mm
    # anatomy sanity in the project frame: helix top above the lobule, tragus in front of the helix back,
    # canal entrance deeper (more medial) than the antitragus tip
    assert v[landmarks["helix_top"], 2] - v[landmarks["lobule_bottom"], 2] > 45
    assert v[landmarks["tragus_tip"], 0] > v[landmarks["helix_back"], 0] + 20
    assert v[landmarks["canal_entrance"], 1] < v[landmarks["antitragus_tip"], 1]


def test_pinna_segmentation_finds_the_pinna_in_a_crop_with_skin(sonicom):
    crop = load_left_pinna(sonicom / "P143" / "pinna_left_crop.ply")
    region = pinna_region(crop, margin_mm=6.0)
    inside = region[crop.faces].all(axis=1)
    share = crop.area_faces[inside].sum() / crop.area
    assert 0.25 < share < 0.65  # by area, the crop is largely head skin around the pinna
    kept = crop.vertices[region]
    assert np.ptp(kept[:, 2]) > 55  # the whole pinna height is kept
    assert kept[:, 1].max() == crop.vertices[:, 1].max()  # the most lateral point (helix) is pinna


def test_segmentation_refuses_a_non_ear():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=40.0)
    with pytest.raises(PpmError, match="does not look like a pinna"):
        pinna_region(sphere)


@pytest.mark.slow
def test_leave_one_out_build_reuses_the_topology(tmp_path, sonicom):
    """A reduced build (one subject's two ears, one round) on the packaged topology: same vertex order,
    landmarks carried over, the left-out subjects recorded, and the result fits its scans."""
    data = tmp_path / "data"
    (data / "P143").mkdir(parents=True)
    for name in ("pinna_left_crop.ply", "pinna_right_crop.ply"):
        shutil.copy(sonicom / "P143" / name, data / "P143" / name)
    shutil.copytree(data / "P143", data / "P067")  # a stand-in second subject, left out below
    out = build_template_folder(data, tmp_path / "without_P067", exclude=["P067"],
                                topology_dir=default_template_dir(), rounds=1)
    built = load_template(out)
    default = load_template()
    assert np.array_equal(built.faces, default.faces)
    assert load_landmarks(built) == load_landmarks(default)
    provenance = json.loads((out / "provenance.json").read_text())
    assert provenance["excluded_subjects"] == ["P067"]
    assert {s["subject"] for s in provenance["scans"]} == {"P143"}
    for residual in provenance["registration_residuals"]:
        assert residual["median_mm"] < 0.2
    assert (out / LANDMARKS_NAME).is_file()
    with pytest.raises(PpmError, match="exclude names subjects not in"):
        build_template_folder(data, tmp_path / "x", exclude=["P999"], topology_dir=default_template_dir())
