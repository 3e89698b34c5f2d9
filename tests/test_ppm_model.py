"""The PPM rig in real bpy: parameter count, exact rest pose, locality, smoothness, .blend round trip."""
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import trimesh

from ppm.errors import PpmError
from ppm.parameters import PinnaParameters, bounds, model_layout, parameter_specs, random_parameters
from ppm.template import load_template


def _local(params: PinnaParameters) -> PinnaParameters:
    """The same parameters without the parent bone (its affine map is checked on its own)."""
    return params.with_values({s.name: s.default for s in parameter_specs() if s.target == "Size-Bendy"})


def test_default_parameters_reproduce_the_template_bit_for_bit(model):
    template = load_template()
    vertices = model.evaluate(PinnaParameters.default())
    assert vertices.dtype == np.float64
    assert np.array_equal(vertices, template.vertices_mm)
    # and again after a pose, so no state leaks between evaluations
    model.evaluate(PinnaParameters.from_dict({"Rotation_Tragus-End_X": 8.0, "Shape_key_Lobulus-Form": 1.0}))
    assert np.array_equal(model.evaluate(PinnaParameters.default()), template.vertices_mm)


def test_all_144_parameters_are_free(model):
    """Each parameter, moved alone to 80 % of its range, moves the mesh by more than 0.05 mm."""
    rest = model.template_vertices_mm
    lower, upper = bounds()
    dead = []
    for spec, low, high in zip(parameter_specs(), lower, upper):
        value = spec.default + 0.8 * (high - spec.default if high - spec.default >= spec.default - low
                                      else low - spec.default)
        moved = np.linalg.norm(model.evaluate(PinnaParameters.from_dict({spec.name: value})) - rest, axis=1)
        if moved.max() < 0.05:
            dead.append((spec.name, moved.max()))
    assert len(parameter_specs()) == 144
    assert dead == []


def test_parent_bone_is_an_exact_affine_map(model):
    """Location, rotation (ZYX, degrees) and anisotropic scale of Size-Bendy act on the whole pinna as one
    affine map about the bone head: x' = head + t + R S (x - head)."""
    values = {"Location_Size-Bendy_X": 3.0, "Location_Size-Bendy_Y": -2.0, "Location_Size-Bendy_Z": 1.5,
              "Rotation_Size-Bendy_X": 10.0, "Rotation_Size-Bendy_Y": -5.0, "Rotation_Size-Bendy_Z": 20.0,
              "Scale_Size-Bendy_X": 0.9, "Scale_Size-Bendy_Y": 1.2, "Scale_Size-Bendy_Z": 1.1}
    posed = model.evaluate(PinnaParameters.from_dict(values))
    head = model.rig.parent_head_mm
    ax, ay, az = np.deg2rad([values[f"Rotation_Size-Bendy_{a}"] for a in "XYZ"])
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    rotation = rx @ ry @ rz  # Blender 'ZYX': Z applied first, then Y, then X
    scale = np.diag([values[f"Scale_Size-Bendy_{a}"] for a in "XYZ"])
    shift = np.array([values[f"Location_Size-Bendy_{a}"] for a in "XYZ"])
    expected = head + shift + (model.template_vertices_mm - head) @ (rotation @ scale).T
    np.testing.assert_allclose(posed, expected, atol=1e-3)  # mm; Blender works in float32


def _region(model, names: list[str]) -> np.ndarray:
    column = [model.rig.weight_names.index(name) for name in names]
    return model.rig.weights[:, column].sum(axis=1) > 0


@pytest.mark.parametrize("curve", model_layout()["curves"])
def test_control_bones_act_in_their_curve_region(model, curve):
    """Moving or rotating a curve's control bones, or scaling its bendy bone, moves nothing outside the
    region weighted to that bendy bone, and does move the region."""
    rest = model.template_vertices_mm
    region = _region(model, [f"{curve}-Bendy"])
    assert 0.01 < region.mean() < 0.5  # a named part, not the whole pinna
    for values in ({f"Location_{curve}-Start_Z": 1.0, f"Location_{curve}-End_X": -1.0},
                   {f"Rotation_{curve}-Start_X": 10.0, f"Rotation_{curve}-End_Z": -10.0},
                   {f"Scale_{curve}-Bendy": 1.1}):
        moved = np.linalg.norm(model.evaluate(PinnaParameters.from_dict(values)) - rest, axis=1)
        assert moved[~region].max() < 1e-6, values
        assert moved[region].max() > 0.2, values


@pytest.mark.parametrize("key", list(model_layout()["shape_keys"]))
def test_shape_keys_are_local_and_smooth(model, key):
    """A shape key at its range limit moves vertices only within its radius of its landmark path, by at
    most its amplitude, and the displacement decays smoothly (no jump between neighbours)."""
    from ppm.deformation import rig_layout

    spec = rig_layout()["shape_keys"][key]
    lower, upper = model_layout()["shape_keys"][key]
    rest = model.template_vertices_mm
    index = list(model_layout()["shape_keys"]).index(key)
    offsets = np.linalg.norm(model.rig.shape_key_offsets_mm[index], axis=1)
    region = offsets > 0
    for weight in {lower, upper} - {0.0}:
        posed = model.evaluate(PinnaParameters.from_dict({f"Shape_key_{key}": weight}))
        moved = np.linalg.norm(posed - rest, axis=1)
        assert moved[~region].max() < 1e-6
        assert moved.max() == pytest.approx(abs(spec["amplitude_mm"] * weight), rel=0.05)
        mesh = trimesh.Trimesh(rest, model.faces, process=False)
        edges = mesh.edges_unique
        slope = np.abs(moved[edges[:, 0]] - moved[edges[:, 1]]) / mesh.edges_unique_length
        # the profile (1 - t²)² has its steepest slope 1.54/radius: nothing may change faster than that;
        # the radial key also fades to 0 on the canal axis over its core radius
        scale_mm = spec["radius_mm"] if spec["kind"] == "normal" else spec["core_radius_mm"]
        assert slope.max() < 1.6 * abs(spec["amplitude_mm"] * weight) / scale_mm + 0.05
    assert region.mean() < 0.15  # a small region, as the spec describes shape keys


def _quality(model, params: PinnaParameters) -> tuple[int, float, float, float]:
    """(flipped faces, min cosine between adjacent faces, min and max edge-length ratio to rest)."""
    rest = trimesh.Trimesh(model.template_vertices_mm, model.faces, process=False)
    posed = trimesh.Trimesh(model.evaluate(_local(params)), model.faces, process=False)
    flipped = int((np.einsum("ij,ij->i", posed.face_normals, rest.face_normals) < 0).sum())
    adjacency = posed.face_adjacency
    cos_adjacent = np.einsum("ij,ij->i", posed.face_normals[adjacency[:, 0]], posed.face_normals[adjacency[:, 1]])
    edges = rest.edges_unique
    ratio = (np.linalg.norm(posed.vertices[edges[:, 0]] - posed.vertices[edges[:, 1]], axis=1)
             / rest.edges_unique_length)
    return flipped, float(cos_adjacent.min()), float(ratio.min()), float(ratio.max())


def test_random_ears_give_a_clean_surface(model):
    """No flipped triangle, no new fold sharper than 120 degrees, no tear (edge stretched over 3x or
    squeezed under 0.3x) for parameter sets drawn uniformly inside half of every typical range (where
    the synthetic and demo ears are drawn; towards the wider bounds the alignment's fold barrier keeps
    the surface clean, see test_ppm_align)."""
    rng = np.random.default_rng(20261123)
    for _ in range(25):
        params = random_parameters(rng, 0.5)
        flipped, cos_adjacent, ratio_min, ratio_max = _quality(model, params)
        assert flipped == 0
        assert cos_adjacent > -0.5
        assert 0.3 < ratio_min and ratio_max < 3.0
        mesh = trimesh.Trimesh(model.evaluate(params), model.faces, process=False)
        assert mesh.is_winding_consistent and np.isfinite(mesh.vertices).all()
        assert mesh.area_faces.min() > 1e-4  # mm²: no degenerate triangle


def test_model_stays_a_manifold_with_one_boundary(model):
    mesh = model.mesh(PinnaParameters.default())
    edges = mesh.edges_sorted
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 2  # every edge in one or two triangles: 2-manifold with boundary
    boundary = edges[trimesh.grouping.group_rows(edges, require_count=1)]
    assert len(trimesh.graph.connected_components(boundary)) == 1  # open only at the outer skin ring


def test_set_parameters_refuses_other_types(model):
    with pytest.raises(PpmError, match="expected PinnaParameters"):
        model.set_parameters({"Scale_Lobulus-Bendy": 1.0})


def test_blend_round_trip_and_exports(model, tmp_path):
    params = PinnaParameters.from_dict({"Rotation_Helix_up-End_X": 8.0, "Location_Tragus-Start_Z": 1.0,
                                        "Shape_key_Cavum_conchae-Depth": -0.6, "Scale_Size-Bendy_Y": 1.1})
    expected = model.evaluate(params)
    blend = model.save_blend(tmp_path / "posed.blend")
    for suffix in (".ply", ".obj"):
        exported = trimesh.load(model.export(tmp_path / f"posed{suffix}"), process=False, force="mesh")
        np.testing.assert_allclose(exported.vertices, expected, atol=1e-4)
    # read it back in a fresh Blender process (opening a .blend replaces this process's scene)
    script = textwrap.dedent(f"""
        import numpy as np
        from ppm.model import PinnaModel
        model = PinnaModel.from_blend({str(blend)!r})
        np.save({str(tmp_path / 'back.npy')!r}, model.evaluate())
        print(model.parameters['Rotation_Helix_up-End_X'])
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "8.0"
    back = np.load(tmp_path / "back.npy")
    np.testing.assert_allclose(back, expected, atol=1e-4)  # mm: float32 storage in the .blend


def test_from_blend_refuses_missing_and_foreign_files(tmp_path):
    from ppm.model import PinnaModel

    with pytest.raises(PpmError, match="no such .blend file"):
        PinnaModel.from_blend(tmp_path / "missing.blend")


def test_progress_lines_estimate_the_time_left():
    import logging

    from core.progress import Progress

    now = [100.0]
    progress = Progress(4, "template registrations", logging.getLogger("test"), clock=lambda: now[0])
    assert progress.seconds_left() is None
    now[0] += 60.0
    line = progress.step("P039")
    assert line == "template registrations: 1/4 done (P039), 1.0 min elapsed, about 3.0 min left"
    now[0] += 120.0
    progress.step()
    assert progress.seconds_left() == 180.0  # 90 s per unit so far, 2 left
