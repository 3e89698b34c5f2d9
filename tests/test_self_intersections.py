"""core.self_intersections: which faces of a mesh cross another (the fitted PPM, the layered pinna and the remeshed
head are checked with it)."""
import numpy as np
import trimesh

from core.self_intersections import self_intersecting_faces


def test_two_triangles_that_pass_through_each_other_are_both_found():
    vertices = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0],            # a triangle in z = 0
                         [2, 2, -5], [2, 2, 5], [8, 8, 0.0]])          # one standing through it
    assert sorted(self_intersecting_faces(vertices, np.array([[0, 1, 2], [3, 4, 5]]))) == [0, 1]


def test_faces_that_only_share_edges_do_not_count_and_a_closed_sphere_has_none():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=90.0)
    assert len(self_intersecting_faces(sphere.vertices, sphere.faces)) == 0
    # push one vertex through the far side of the sphere: the faces around it now cross the sphere's other side
    vertices = np.array(sphere.vertices)
    vertices[0] *= -1.3
    crossing = self_intersecting_faces(vertices, sphere.faces)
    assert len(crossing) >= 5 and set(np.flatnonzero((sphere.faces == 0).any(axis=1))) <= set(crossing)
