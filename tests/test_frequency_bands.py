"""stitching.frequency_bands: a coarser mesh of a real head for a band of low frequencies keeps the ear-canal
source's triangles exactly and the surface closed, with far fewer elements."""
import numpy as np
import pytest
import trimesh

from mesh2hrtf_io.checks import min_angles_deg
from mesh2hrtf_io.ear_canal import ear_canal_elements
from stitching.frequency_bands import band_mesh
from stitching.remesh import Band


def test_a_band_mesh_of_a_real_head_keeps_the_source(sonicom):
    head = trimesh.load(sonicom / "P143" / "head_graded_left.ply", process=False, force="mesh")
    pinna = np.asarray(trimesh.load(sonicom / "P143" / "pinna_left_crop.ply", process=False).vertices)
    source = ear_canal_elements(head, "left")
    bands = (Band(12.0, 3.0, 0.3), Band(30.0, 5.0, 0.5), Band(60.0, 8.0, 0.8), Band(np.inf, 12.0, 1.2))
    mesh, kept = band_mesh(head, source, pinna, bands, source="P143")
    assert len(mesh.faces) < 0.4 * len(head.faces)  # 31,466 -> about 9,000
    assert mesh.is_watertight and mesh.is_winding_consistent
    np.testing.assert_allclose(mesh.triangles_center[kept], head.triangles_center[source], atol=1e-9)
    assert mesh.area_faces[kept].sum() == pytest.approx(head.area_faces[source].sum(), rel=1e-12)
    assert min_angles_deg(mesh.vertices, mesh.faces).min() > 5.0
    # the surface stays where it was: every band-mesh vertex within the coarsest band's deviation of the head
    assert trimesh.proximity.closest_point(head, mesh.vertices[::20])[1].max() < 1.2
