"""ppm.align.detail: the personal-detail layer takes a detail the PPM cannot (a smooth 0.8 mm bulge) from a
defective scan, ignores holes, outliers and spikes, keeps the rim, folds nothing, and lives in the .blend as the
shape key Personal_detail (weight 0: the PPM as fitted)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import trimesh

from ppm.align.detail import (DetailSettings, closest_facing, closest_within, evidence_fade, personal_detail, rim_taper,
                              rim_vertices, surface_roughness_deg, unfold)
from ppm.align.synthetic import add_scan_defects
from ppm.align.target import target_from_mesh
from ppm.errors import PpmError
from ppm.parameters import PinnaParameters, random_parameters

BULGE_MM = 0.8
BULGE_SIGMA_MM = 3.0


@pytest.fixture(scope="module")
def posed(model):
    """The packaged PPM at random parameters: (vertices mm, faces, vertex normals)."""
    model.set_parameters(random_parameters(np.random.default_rng(5), 0.5))
    vertices = model.evaluate()
    mesh = trimesh.Trimesh(vertices, model.faces, process=False)
    yield vertices, model.faces, np.asarray(mesh.vertex_normals)
    model.set_parameters(PinnaParameters.default())


def _bulge(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, int]:
    """A smooth 0.8 mm bulge along the normals, centred on the vertex farthest along the surface from the rim
    (deep in the pinna: the detail a template of other ears does not have); (n, 3) displacement, its centre."""
    taper = rim_taper(vertices, faces, 40.0)
    centre = int(np.argmax(taper))
    weight = np.exp(-np.sum((vertices - vertices[centre]) ** 2, axis=1) / (2 * BULGE_SIGMA_MM ** 2))
    return BULGE_MM * weight[:, None] * normals, centre


def _spiked(scan: trimesh.Trimesh, rng: np.random.Generator, share: float = 0.01) -> trimesh.Trimesh:
    vertices = np.array(scan.vertices)
    picked = rng.random(len(vertices)) < share
    vertices[picked] += 3.0 * np.asarray(scan.vertex_normals)[picked]
    return trimesh.Trimesh(vertices, scan.faces, process=False)


def test_the_layer_takes_a_detail_from_a_defective_scan_and_nothing_else(posed):
    vertices, faces, normals = posed
    bulge, centre = _bulge(vertices, faces, normals)
    rng = np.random.default_rng(11)
    truth = trimesh.Trimesh(vertices + bulge, faces, process=False)
    # a hole away from the bulge, noise, outliers thrown off and spikes along the normals
    far = np.flatnonzero((np.linalg.norm(vertices - vertices[centre], axis=1) > 15.0) & (rim_taper(vertices, faces, 8.0) == 1.0))
    scan = add_scan_defects(truth, rng, noise_mm=0.05, holes=1, hole_radius_mm=3.0, outlier_share=0.02,
                            hole_centres=far)
    scan = _spiked(scan, rng)
    target = target_from_mesh(scan, "bulged PPM scan")
    detail = personal_detail(vertices, faces, target)
    moved = vertices + detail.displacement_mm

    # surface to surface (the layer may slide vertices along the surface): the bulge's vertices to the truth
    bulged = np.linalg.norm(bulge, axis=1) > 0.4
    before = trimesh.proximity.closest_point(truth, vertices[bulged])[1]
    after = trimesh.proximity.closest_point(truth, moved[bulged])[1]
    assert np.median(after) < 0.15 * np.median(before)  # most of the bulge is taken
    off_truth = trimesh.proximity.closest_point(truth, moved)[1]
    assert off_truth.max() < 0.5  # no spike (3 mm) or outlier (2-8 mm) is followed anywhere
    flat = np.linalg.norm(bulge, axis=1) < 0.01
    assert np.percentile(off_truth[flat], 95) < 0.1  # where the scan agrees with the PPM, the surface stays
    # where the scan has a hole, the PPM's shape stays
    seen = trimesh.proximity.closest_point(trimesh.Trimesh(scan.vertices, scan.faces, process=False), vertices)[1]
    in_hole = flat & (seen > 1.5)
    assert in_hole.sum() > 5 and detail.size_mm[in_hole].max() < 0.1
    # the rim the stitch joins stays put, and no face folds
    np.testing.assert_array_equal(detail.displacement_mm[rim_vertices(faces)], 0.0)
    before_normals, after_normals = (trimesh.Trimesh(v, faces, process=False).face_normals for v in (vertices, moved))
    assert np.einsum("ij,ij->i", before_normals, after_normals).min() > 0.0
    # nor creases against a neighbour beyond the stitch's fold test (120 deg) where the PPM did not
    creases = [np.degrees(trimesh.Trimesh(v, faces, process=False).face_adjacency_angles) for v in (vertices, moved)]
    assert np.all(creases[1] <= np.maximum(120.0, creases[0]) + 1e-6)
    assert detail.summary()["displacement_max_mm"] == pytest.approx(detail.size_mm.max(), abs=1e-4)


def test_the_layer_s_summary_counts_faces_crossing_each_other_before_and_after(model, posed):
    """add_personal_detail's summary says where the fit and the layered pinna pass through themselves (MeshLab's test):
    a PPM at moderate parameters and a smooth bulge cross nowhere."""
    from ppm.align.detail import add_personal_detail

    vertices, faces, normals = posed
    bulge, _ = _bulge(vertices, faces, normals)
    target = target_from_mesh(trimesh.Trimesh(vertices + bulge, faces, process=False), "bulged PPM")
    try:
        _, summary = add_personal_detail(model, target)
    finally:
        model.set_detail_weight(0.0)
    assert summary["self_intersecting_faces"] == {"ppm": 0, "ppm_detail": 0}
    assert summary["ppm_detail"]["max_mm"] < 0.5 * summary["ppm"]["max_mm"]  # the bulge (0.8 mm) is taken


def test_a_scan_of_another_place_moves_nothing(posed):
    """A scan 30 mm away (another ear, a wrong crop) gives no evidence within reach: the PPM stays as fitted."""
    vertices, faces, _ = posed
    target = target_from_mesh(trimesh.Trimesh(vertices + [0.0, 30.0, 0.0], faces, process=False), "moved PPM")
    detail = personal_detail(vertices, faces, target)
    assert not detail.trusted.any() and detail.size_mm.max() == 0.0


def test_the_layer_is_a_shape_key_of_the_blend(model, posed, tmp_path):
    vertices, faces, normals = posed
    bulge, _ = _bulge(vertices, faces, normals)
    mismatch = model.set_personal_detail(bulge)
    assert mismatch < 1e-3
    np.testing.assert_allclose(model.evaluate(), vertices + bulge, atol=2e-3)
    model.set_detail_weight(0.0)
    np.testing.assert_allclose(model.evaluate(), vertices, atol=1e-4)
    model.set_detail_weight(1.0)
    blend = tmp_path / "detail.blend"
    model.save_blend(blend)
    np.save(tmp_path / "expected.npy", model.evaluate())
    model.set_detail_weight(0.0)
    # a fresh process opens it: the pose and the key at weight 1 come back; weight 0 is the PPM as fitted
    script = textwrap.dedent(f"""
        import numpy as np
        from ppm.model import PinnaModel
        model = PinnaModel.from_blend({str(blend)!r})
        np.save({str(tmp_path / 'with.npy')!r}, model.evaluate())
        model.set_detail_weight(0.0)
        np.save({str(tmp_path / 'without.npy')!r}, model.evaluate())
        print(model.detail_weight)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    np.testing.assert_allclose(np.load(tmp_path / "with.npy"), np.load(tmp_path / "expected.npy"), atol=1e-4)
    np.testing.assert_allclose(np.load(tmp_path / "without.npy"), vertices, atol=1e-3)
    with pytest.raises(PpmError, match="expected finite"):
        model.set_personal_detail(np.full_like(vertices, np.nan))


def test_facing_pairs_find_the_near_face_of_a_thin_sheet():
    """A slab 1 mm thick (mm; like a lobule): a point 0.3 mm above its lower face, facing up like its upper face,
    is nearest to the lower face (turned away); the facing search finds the upper one, 0.7 mm up."""
    slab = trimesh.creation.box(extents=(20.0, 20.0, 1.0))
    slab.vertices[:, 2] += 0.5  # faces at z = 0 (normal -z) and z = 1 (normal +z)
    slab = trimesh.Trimesh(slab.vertices, slab.faces).subdivide().subdivide()
    point, up = np.array([[0.3, -0.2, 0.3]]), np.array([[0.0, 0.0, 1.0]])
    nearest, distance, _ = closest_within(slab, point, 4.0)
    assert distance[0] == pytest.approx(0.3) and nearest[0, 2] == pytest.approx(0.0)
    facing, distance, triangle = closest_facing(slab, point, up, 4.0, 45.0)
    assert distance[0] == pytest.approx(0.7) and facing[0, 2] == pytest.approx(1.0)
    assert slab.face_normals[triangle[0]] @ up[0] == pytest.approx(1.0)
    # a point far beyond reach gets no pair
    _, distance, _ = closest_facing(slab, np.array([[0.0, 0.0, 40.0]]), up, 4.0, 45.0)
    assert np.isinf(distance[0])


def test_the_roughness_guard_keeps_the_layer_off_a_noisy_scan_s_noise(posed):
    """A scan of the PPM itself with 0.5 mm noise along its normals (the hard defect level's): the whole schedule
    follows the noise (rougher, farther from the true surface); the roughness guard stops it at a stiffer stage,
    nearer the truth and within its limit of the PPM's own roughness."""
    vertices, faces, normals = posed
    rng = np.random.default_rng(2)
    noisy = vertices + rng.normal(0.0, 0.5, len(vertices))[:, None] * normals
    target = target_from_mesh(trimesh.Trimesh(noisy, faces, process=False), "noisy PPM scan")
    own = surface_roughness_deg(vertices, faces)
    runs = {limit: personal_detail(vertices, faces, target, DetailSettings.packaged(roughness_limit_deg=limit))
            for limit in (None, 10.0)}
    rough = {limit: surface_roughness_deg(vertices + run.displacement_mm, faces) for limit, run in runs.items()}
    off = {limit: np.median(np.linalg.norm(run.displacement_mm, axis=1)) for limit, run in runs.items()}
    assert rough[None] > own + 10.0  # the supple end follows the noise
    assert rough[10.0] <= own + 10.0 and runs[10.0].stages < len(DetailSettings.packaged().stiffness_mm2)
    assert off[10.0] < off[None]  # the truth is the PPM itself: the guarded layer strays less from it


def test_the_evidence_fade_keeps_the_ppm_where_the_scan_saw_nothing(posed):
    """A scan of the PPM's upper half pushed 0.5 mm out along its normals: without the fade the smooth field reaches
    into the lower half the scan never saw; with evidence_fade_mm the vertices beyond twice it from any trusted pair
    stay exactly where the PPM put them, and the seen half still takes the offset."""
    line = np.stack([np.arange(6.0), np.zeros(6), np.zeros(6)], axis=1)
    assert np.allclose(evidence_fade(line, np.arange(6) == 0, 2.0), [1.0, 1.0, 1.0, 0.5, 0.0, 0.0])
    assert not evidence_fade(line, np.zeros(6, bool), 2.0).any()
    vertices, faces, normals = posed
    upper = vertices[:, 2] > np.median(vertices[:, 2])
    shifted = trimesh.Trimesh(vertices + 0.5 * normals, faces, process=False)
    shifted.update_faces(upper[faces].all(axis=1))
    shifted.remove_unreferenced_vertices()
    target = target_from_mesh(shifted, "upper half of the PPM, 0.5 mm out")
    runs = {fade: personal_detail(vertices, faces, target, DetailSettings.packaged(evidence_fade_mm=fade))
            for fade in (None, 2.0)}
    below = vertices[:, 2] < np.median(vertices[:, 2]) - 10.0  # 10 mm and more below the scan's lower edge
    size = {fade: np.linalg.norm(run.displacement_mm, axis=1) for fade, run in runs.items()}
    seen = upper & (rim_taper(vertices, faces, 8.0) == 1.0) & (vertices[:, 2] > np.median(vertices[:, 2]) + 5.0)
    assert np.median(size[None][below]) > 0.02 and size[None][below].max() > 0.08  # the field reaches past the scan
    assert np.max(size[2.0][below]) == 0.0
    assert abs(np.median(size[2.0][seen]) - 0.5) < 0.1


def test_smoothing_a_fold_keeps_the_field_around_it_where_halving_dents_it():
    """A flat grid (1 mm spacing) lifted 1 mm by the field, one inner vertex also thrown 2.5 mm sideways over its
    neighbours (folding its faces, as a wrong pair on a hard scan does). Halving pulls the fold's vertices back
    towards the PPM and leaves a dent in the lift; smoothing the field around the fold first irons it out with the
    lift kept. Neither leaves a folded face or moves the held rim."""
    xs, ys = np.meshgrid(np.arange(13.0), np.arange(13.0))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    index = np.arange(13 * 13).reshape(13, 13)
    quads = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    held = np.isin(np.arange(len(vertices)), rim_vertices(faces))
    field = np.where(held[:, None], 0.0, np.array([0.0, 0.0, 1.0]))
    thrown = index[6, 6]
    field[thrown] += [2.5, 0.0, 0.0]
    settings = {rounds: DetailSettings.packaged(fold_smoothing_rounds=rounds) for rounds in (0, 20)}
    halved, halvings, _ = unfold(vertices, faces, field, held, settings[0])
    smoothed, halvings_after, smoothings = unfold(vertices, faces, field, held, settings[20])
    assert halvings > 0 and smoothings > 0 and halvings_after == 0
    ring = np.unique(faces[np.any(faces == thrown, axis=1)])
    assert halved[ring, 2].min() < 0.6  # the lift dented around the fold
    assert smoothed[ring, 2].min() > 0.9  # the lift kept
    reference = trimesh.Trimesh(vertices, faces, process=False).face_normals
    for result in (halved, smoothed):
        moved = trimesh.Trimesh(vertices + result, faces, process=False).face_normals
        assert np.einsum("ij,ij->i", moved, reference).min() > 0.0
        np.testing.assert_array_equal(result[held], 0.0)


def test_the_layer_s_evidence_takes_a_reconstruction_s_fill_of_a_hole_and_not_its_balloon(posed):
    """The PPM pushed 1 mm out along its normals, scanned with a 7 mm hole deep in the pinna: the reconstruction's
    fill (hole_fill_mm 2) lies in the hole only, not round the crop's edges where Poisson balloons (the surround
    test), and joins the layer's evidence; with hole_fill_mm null the evidence is the scan itself. Drawn towards the
    joined evidence the layer holds the rim and folds nothing."""
    import bpy  # noqa: F401  (before pymeshlab)
    from scipy.spatial import cKDTree

    from stitching.reconstruction import hole_fill, layer_evidence, reconstruction_settings

    vertices, faces, normals = posed
    centre = int(np.argmax(rim_taper(vertices, faces, 40.0)))
    truth = trimesh.Trimesh(vertices + 1.0 * normals, faces, process=False)
    scan = add_scan_defects(truth, np.random.default_rng(3), noise_mm=0.02, holes=1, hole_radius_mm=7.0,
                            outlier_share=0.0, hole_centres=[centre])
    target = target_from_mesh(scan, "PPM 1 mm out, a hole deep in the pinna")
    assert layer_evidence(target, DetailSettings.packaged(hole_fill_mm=None)) is target  # the scan alone
    fill = hole_fill(scan, 2.0)
    assert len(fill.faces) > 20
    assert cKDTree(scan.vertices).query(fill.triangles_center)[0].min() > 2.0
    assert np.linalg.norm(fill.triangles_center - truth.vertices[centre], axis=1).max() < 7.0  # in the hole only
    unsurrounded = hole_fill(scan, 2.0, {**reconstruction_settings(), "fill": {"surround_radius_mm": 8.0,
                                                                               "open_angle_deg": 360.0}})
    assert unsurrounded.area > 5.0 * fill.area  # what the surround test keeps out: the balloon round the edges
    settings = DetailSettings.packaged(hole_fill_mm=2.0)
    evidence = layer_evidence(target, settings)
    assert len(evidence.mesh.faces) == len(scan.faces) + len(fill.faces) and "fill" in evidence.source
    layer = personal_detail(vertices, faces, evidence, settings)
    np.testing.assert_array_equal(layer.displacement_mm[rim_vertices(faces)], 0.0)
    moved = trimesh.Trimesh(vertices + layer.displacement_mm, faces, process=False).face_normals
    assert np.einsum("ij,ij->i", moved, trimesh.Trimesh(vertices, faces, process=False).face_normals).min() > 0.0


def test_the_layer_ends_no_more_supple_than_the_scan_s_noise(posed):
    """A scan of the PPM itself with 0.5 mm noise along its normals (the hard level's): with noise_stiffness_factor 1
    the schedule ends at the scan's own noise squared (read from the scan: 0.45-0.65 mm) instead of 0.1 mm², and the
    layer strays less from the truth (the PPM itself); on the same scan without noise the schedule stays."""
    vertices, faces, normals = posed
    rng = np.random.default_rng(2)
    noisy = vertices + rng.normal(0.0, 0.5, len(vertices))[:, None] * normals
    target = target_from_mesh(trimesh.Trimesh(noisy, faces, process=False), "noisy PPM scan")
    packaged = personal_detail(vertices, faces, target)
    floored = personal_detail(vertices, faces, target, DetailSettings.packaged(noise_stiffness_factor=1.0))
    assert packaged.noise_mm is None and packaged.stiffness_mm2 == DetailSettings.packaged().stiffness_mm2
    assert 0.45 <= floored.noise_mm <= 0.65
    assert floored.stiffness_mm2[-1] == pytest.approx(floored.noise_mm ** 2, abs=1e-4)
    assert floored.summary()["stiffness_end_mm2"] == floored.stiffness_mm2[-1]
    off = {name: np.median(np.linalg.norm(run.displacement_mm, axis=1))
           for name, run in (("packaged", packaged), ("floored", floored))}
    assert off["floored"] < 0.8 * off["packaged"]
    clean = target_from_mesh(trimesh.Trimesh(vertices, faces, process=False), "clean PPM scan")
    assert personal_detail(vertices, faces, clean, DetailSettings.packaged(noise_stiffness_factor=1.0)
                           ).stiffness_mm2 == DetailSettings.packaged().stiffness_mm2


def test_a_layer_led_by_the_scan_s_points_sags_less_between_them():
    """A sphere (radius 12 mm) scanned with 1.8 mm edges: the chords between its points lie up to 0.03 mm inside it.
    The PPM, a finer sphere 0.4 mm too large, pulled by the packaged layer sits inside the sphere by about the chords'
    sag (its vertices go to the scan's triangulated surface); with the vertices' pull weighted 0.3
    (forward_weight), the scan's points lead and the sag shrinks; with no such pull the points alone hold it."""
    radius = 12.0
    fine = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    scan = target_from_mesh(trimesh.creation.icosphere(subdivisions=3, radius=radius), "coarse sphere scan")
    ppm = np.asarray(fine.vertices) * (radius + 0.4) / radius
    sag = {}
    for weight in (1.0, 0.3, 0.0):
        layer = personal_detail(ppm, fine.faces, scan, DetailSettings.packaged(forward_weight=weight, hole_fill_mm=None))
        sag[weight] = float(np.mean(np.linalg.norm(ppm + layer.displacement_mm, axis=1) - radius))
    assert -0.035 < sag[1.0] < -0.015  # inside, by the chords
    assert sag[1.0] < sag[0.3] < 0.0
    assert abs(sag[0.0]) < abs(sag[1.0])


def test_stray_points_settled_no_longer_lift_the_layer_off_the_surface():
    """A sphere (radius 12 mm) scanned with 1.8 mm edges, 5 % of its points thrown 1.5-2.5 mm outward: near enough
    for the isolation test to keep them, so their tents of faces pull the layer out. With outlier_sigmas the strays
    are found (all 39) and settled onto their neighbours' surface, and the layer's worst vertices come back to the
    sphere."""
    rng = np.random.default_rng(11)
    radius = 12.0
    fine = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    coarse = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    vertices = np.array(coarse.vertices)
    thrown = rng.random(len(vertices)) < 0.05
    vertices[thrown] *= (radius + rng.uniform(1.5, 2.5, int(thrown.sum())))[:, None] / radius
    scan = target_from_mesh(trimesh.Trimesh(vertices, coarse.faces, process=False), "sphere scan with strays")
    ppm = np.asarray(fine.vertices) * (radius + 0.4) / radius
    error = {}
    for sigmas in (None, 3.0):
        settings = DetailSettings.packaged(outlier_sigmas=sigmas, hole_fill_mm=None)
        layer = personal_detail(ppm, fine.faces, scan, settings)
        error[sigmas] = np.abs(np.linalg.norm(ppm + layer.displacement_mm, axis=1) - radius)
        if sigmas is not None:
            assert layer.strays >= 0.8 * thrown.sum()
            assert layer.summary()["stray_scan_points"] == layer.strays
    assert np.percentile(error[None], 99) > 0.2  # the tents lift the layer (0.31 mm; median 0.024)
    assert np.percentile(error[3.0], 99) < 0.06  # back to the chords' sag (0.034 mm)
