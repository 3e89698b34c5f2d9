"""Stitching the PPM pinna onto real heads and remeshing for BEM: closed manifold, edge lengths, round
trip with the head's own pinna, ear-canal source, bad input (real pymeshlab, real scans)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from ppm.align import align, prepare_target
from stitching import StitchError, ear_canal_elements, replace_pinna, self_intersections, validate_head
from stitching.pipeline import remesh_files, stitch_files
from mesh2hrtf_io.checks import min_angles_deg, sliver_count
from stitching.remesh import face_distance_to, remove_slivers


@pytest.fixture(scope="module")
def p143_head(sonicom):
    return trimesh.load(sonicom / "P143" / "head_graded_left.ply", process=False)


@pytest.fixture(scope="module")
def p143_ppm_pinna(model, sonicom):
    """The PPM (default template) fitted to P143's left pinna scan."""
    from ppm.parameters import PinnaParameters

    target = prepare_target(sonicom / "P143" / "pinna_left_crop.ply", side="left", margin_mm=3.0)
    result = align(model, target)
    model.set_parameters(PinnaParameters.default())
    return trimesh.Trimesh(result.vertices_mm, model.faces, process=False)


def _own_pinna_region(head: trimesh.Trimesh) -> trimesh.Trimesh:
    """The head's own left pinna with a ring of skin, cut along a smooth ellipse (seen from the side)."""
    c = head.triangles_center
    inside = (((c[:, 0] + 8) / 40) ** 2 + ((c[:, 2] - 2) / 48) ** 2 < 1) & (c[:, 1] > 50)
    region = trimesh.Trimesh(head.vertices, head.faces[inside], process=False)
    region.remove_unreferenced_vertices()
    return max(region.split(only_watertight=False), key=lambda m: len(m.faces))


def test_round_trip_with_the_heads_own_pinna_changes_nothing_outside_the_seam(p143_head):
    own = _own_pinna_region(p143_head)
    stitched = replace_pinna(p143_head, own)
    mesh = stitched.mesh
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    assert self_intersections(mesh) == 0
    outside_seam = trimesh.Trimesh(mesh.vertices, mesh.faces[stitched.origin != 2], process=False)
    samples = trimesh.sample.sample_surface_even(outside_seam, 20000, seed=3)[0]
    _, distance, _ = trimesh.proximity.closest_point(p143_head, samples)
    assert distance.max() < 0.1  # mm: head and pinna faces are the original ones
    seam = trimesh.Trimesh(mesh.vertices, mesh.faces[stitched.origin == 2], process=False)
    _, seam_distance, _ = trimesh.proximity.closest_point(p143_head, seam.triangles_center)
    assert np.percentile(seam_distance, 95) < 0.5  # the strip spans a ~2 mm gap on the skin
    assert 1.5 <= stitched.rim_gap_mm <= 4.0


def test_fitted_ppm_pinna_gives_a_bem_ready_head(tmp_path, sonicom, p143_ppm_pinna):
    pinna_path = tmp_path / "aligned_pinna.ply"
    p143_ppm_pinna.export(pinna_path)
    head_path = sonicom / "P143" / "head_graded_left.ply"
    stitch = stitch_files(head_path, pinna_path, tmp_path / "stitched.ply", tmp_path / "stitch.json")
    assert stitch["closed"] and stitch["seam_faces"] > 100
    report = remesh_files(tmp_path / "stitched.ply", pinna_path, tmp_path / "head.ply", tmp_path / "validation.json")
    assert report["ok"] and report["closed"] and report["self_intersecting_faces"] == 0 and report["normals_outward"]
    assert report["sliver_faces"] == 0 and report["min_angle_deg"] >= 5.0
    assert abs(report["pinna_edge_mm"]["median"] - 1.0) <= 0.15
    assert 20_000 <= report["n_triangles"] <= 45_000
    assert report["pinna_to_head_mm"]["p95"] < 0.1  # the seam does not distort the pinna
    assert report["max_frequency_hz_6_per_wavelength_pinna"] > 20_000
    assert json.loads((tmp_path / "validation.json").read_text())["n_triangles"] == report["n_triangles"]
    remeshed = trimesh.load(tmp_path / "head.ply", process=False)
    # the right pinna region is still there (coarser, but the head keeps its shape on that side)
    right = remeshed.vertices[:, 1].min()
    assert right == pytest.approx(trimesh.load(head_path, process=False).vertices[:, 1].min(), abs=2.0)
    left_ear = ear_canal_elements(remeshed, "left")
    assert report["ear_elements"]["left"] == left_ear.tolist() and len(report["ear_elements"]["right"]) >= 1
    depth = remeshed.triangles_center[left_ear][:, 1].mean()
    assert 50 < depth < 80  # in the concha / canal entrance, not on the tragus or helix rim
    assert face_distance_to(p143_ppm_pinna.vertices, remeshed)[left_ear].min() < 1.0


def test_ear_canal_elements_of_a_real_head(sonicom):
    head = trimesh.load(sonicom / "P039" / "head_graded_left.ply", process=False)
    for side, sign in (("left", 1), ("right", -1)):
        faces = ear_canal_elements(head, side)
        centre = head.triangles_center[faces].mean(axis=0)
        assert 40 < sign * centre[1] < 90 and abs(centre[0]) < 15 and abs(centre[2]) < 15
        assert head.area_faces[faces].sum() >= 4.0


@pytest.mark.parametrize("subject", ["P039", "P067", "P143"])
def test_the_source_sits_in_the_middle_of_the_blocked_canal_floor(sonicom, subject):
    """The ray from the interaural centre leaves the SONICOM heads on the wall behind the tragus; the source is
    the middle of the flat patch the scan closed the canal with, 1-7 mm deeper, its faces looking out along +y."""
    from mesh2hrtf_io.ear_canal import _ray_exit, canal_floor

    head = trimesh.load(sonicom / subject / "head_graded_left.ply", process=False)
    hit, face = _ray_exit(head, np.array([0.0, 1.0, 0.0]), "left", subject)
    floor = canal_floor(head, hit, face, np.array([0.0, 1.0, 0.0]))
    assert floor is not None and 50.0 < head.area_faces[floor].sum() < 110.0  # a canal entrance, 8-12 mm across
    faces = ear_canal_elements(head, "left")
    centre = head.triangles_center[faces].mean(axis=0)
    assert 0.5 < hit[1] - centre[1] < 8.0 and np.ptp(head.triangles_center[floor][:, 1]) < 2.0
    assert head.face_normals[faces][:, 1].mean() > 0.9 and 4.0 <= head.area_faces[faces].sum() < 5.0
    assert set(faces) <= set(floor)
    # a sphere has no pit: its source stays where the ray leaves it
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=80.0)
    cap = ear_canal_elements(sphere, "left")
    assert sphere.triangles_center[cap][:, 1].min() > 79.0


def test_bad_input_is_named_and_nothing_is_written(tmp_path, p143_head, p143_ppm_pinna, sonicom):
    open_head = trimesh.Trimesh(p143_head.vertices, p143_head.faces[1:], process=False)
    with pytest.raises(StitchError, match="open"):
        replace_pinna(open_head, p143_ppm_pinna)
    with pytest.raises(StitchError, match="metres"):
        replace_pinna(trimesh.Trimesh(p143_head.vertices / 1000, p143_head.faces, process=False), p143_ppm_pinna)
    mirrored = p143_ppm_pinna.copy()
    mirrored.vertices[:, 1] *= -1
    with pytest.raises(StitchError, match="LEFT pinna"):
        replace_pinna(p143_head, mirrored)
    shifted = p143_ppm_pinna.copy()
    shifted.apply_translation([0, 25, 0])
    with pytest.raises(StitchError, match="rest on the head"):
        replace_pinna(p143_head, shifted)
    with pytest.raises(StitchError, match="millimetres"):
        replace_pinna(p143_head, trimesh.Trimesh(p143_ppm_pinna.vertices / 1000, p143_ppm_pinna.faces))
    (tmp_path / "empty.ply").write_bytes(b"")
    with pytest.raises(StitchError, match="missing or empty"):
        stitch_files(sonicom / "P143" / "head_graded_left.ply", tmp_path / "empty.ply", tmp_path / "out.ply",
                     tmp_path / "out.json")
    assert not (tmp_path / "out.ply").exists() and not (tmp_path / "out.json").exists()


def test_the_own_pinna_region_takes_in_the_faces_its_rim_tests_miss(model, sonicom):
    """On P039 (and P067) the faces inside the fitted PPM's rim left holes in the own pinna region (under the
    helix fold): the region has them back, one boundary loop, and goes through the stitch like P143's."""
    from stitching.loops import boundary_loops
    from stitching.replace_pinna import own_pinna_region

    head = trimesh.load(sonicom / "P039" / "head_graded_left.ply", process=False)
    target = prepare_target(sonicom / "P039" / "pinna_left_crop.ply", side="left", margin_mm=3.0)
    pinna = trimesh.Trimesh(align(model, target).vertices_mm, model.faces, process=False)
    own = own_pinna_region(head, pinna, pinna_source="P039 fit")
    assert len(boundary_loops(own)) == 1 and 10000 < len(own.faces) < 25000
    stitched = replace_pinna(head, own).mesh
    assert stitched.is_watertight and stitched.is_winding_consistent and stitched.volume > 0


def test_the_heads_own_pinna_under_a_fitted_ppm_goes_back_through_the_same_path(p143_head, p143_ppm_pinna):
    """The own_pinna control: the head faces inside the fitted PPM's rim, cut out and stitched back, give a
    closed head that lies on the original surface outside the seam."""
    from stitching.replace_pinna import own_pinna_region

    own = own_pinna_region(p143_head, p143_ppm_pinna)
    assert 3000 < len(own.faces) < 20000 and own.vertices[:, 1].min() > 40.0
    stitched = replace_pinna(p143_head, own)
    mesh = stitched.mesh
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    outside_seam = trimesh.Trimesh(mesh.vertices, mesh.faces[stitched.origin != 2], process=False)
    samples = trimesh.sample.sample_surface_even(outside_seam, 20000, seed=5)[0]
    assert trimesh.proximity.closest_point(p143_head, samples)[1].max() < 0.1
    # the pinna itself (concha, helix) is the original: every own-region vertex is a head vertex
    assert trimesh.proximity.closest_point(p143_head, own.vertices)[1].max() < 1e-6
    with pytest.raises(StitchError, match="no head face lies inside"):
        own_pinna_region(p143_head, p143_ppm_pinna.copy().apply_translation([0, -140.0, 0]).apply_transform(
            np.diag([1.0, -1.0, 1.0, 1.0])).apply_translation([0, 150.0, 200.0]))


def test_sliver_triangles_are_remeshed_away_without_moving_the_surface():
    """A 1 mm sphere mesh with one vertex pushed 97 % of the way along an edge (two needles of ~1 deg and the caps
    beside them, the kind of triangle NumCalc spiked on): afterwards no angle is under 10 deg, the surface is
    closed and within 0.05 mm of the input, and a mesh without slivers is returned unchanged."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=30.0)  # ~1.2 mm edges
    assert sliver_count(sphere.vertices, sphere.faces) == 0
    assert remove_slivers(sphere) is sphere
    a, b = sphere.edges_unique[0]
    vertices = sphere.vertices.copy()
    vertices[a] = vertices[a] + 0.97 * (vertices[b] - vertices[a])
    vertices[a] *= 30.0 / np.linalg.norm(vertices[a])  # back onto the sphere
    needles = trimesh.Trimesh(vertices, sphere.faces, process=False)
    assert min_angles_deg(needles.vertices, needles.faces).min() < 3.0 and sliver_count(needles.vertices, needles.faces) >= 2
    repaired = remove_slivers(needles)
    assert min_angles_deg(repaired.vertices, repaired.faces).min() >= 10.0
    assert repaired.is_watertight and repaired.is_winding_consistent and repaired.volume > 0
    radius = np.linalg.norm(repaired.vertices, axis=1)
    assert np.abs(radius - 30.0).max() < 0.05
    assert abs(len(repaired.faces) - len(sphere.faces)) < 200  # only the neighbourhood was remeshed


def test_a_crumple_of_folded_triangles_is_cut_out_and_filled():
    """A 1 mm sphere mesh with one vertex pushed 1.6 edges across its neighbour (its triangles fold over their
    neighbours, as at P067's dataset head below the concha): the head check refuses it, fill_folds leaves no
    dihedral angle above 120 deg and a closed, outward mesh on the sphere (within 0.2 mm: the fill is nearly flat,
    and a 5 mm patch of a 30 mm sphere bulges by 0.1 mm) whose faces farther than 10 mm from the crumple are
    untouched; a mesh without folds is returned as it is."""
    from stitching.remesh import FOLD_DIHEDRAL_DEG, fill_folds, folded_faces

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=30.0)
    assert not folded_faces(sphere).any() and fill_folds(sphere) is sphere
    a, b = sphere.edges_unique[0]
    vertices = sphere.vertices.copy()
    spot = vertices[a] + 1.6 * (vertices[b] - vertices[a])
    vertices[a] = spot * 30.0 / np.linalg.norm(spot)
    crumpled = trimesh.Trimesh(vertices, sphere.faces, process=False)
    assert folded_faces(crumpled).sum() >= 2
    assert not validate_head(crumpled)["ok"] and validate_head(crumpled)["folded_faces"] >= 2
    filled = fill_folds(crumpled)
    assert not folded_faces(filled).any()
    assert np.degrees(filled.face_adjacency_angles).max() < FOLD_DIHEDRAL_DEG
    assert filled.is_watertight and filled.is_winding_consistent and filled.volume > 0
    assert np.abs(np.linalg.norm(filled.vertices, axis=1) - 30.0).max() < 0.2
    far = np.linalg.norm(sphere.triangles_center - spot, axis=1) > 10.0
    kept = {tuple(np.round(t.ravel(), 9)) for t in filled.triangles}
    assert all(tuple(np.round(t.ravel(), 9)) in kept for t in sphere.triangles[far])
    # the remesh's closing repair (folds, slivers, self-intersections, again while a fold is left) leaves none
    from stitching.remesh import repair_folds_and_slivers

    repaired = repair_folds_and_slivers(crumpled)
    report = validate_head(repaired)
    assert report["folded_faces"] == 0 and report["sliver_faces"] == 0 and report["self_intersecting_faces"] == 0
