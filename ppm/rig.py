"""Construction of the PPM rig in Blender (bpy): template mesh, armature with B-Bones, shape keys.

Blender units are millimetres (the scene's unit scale is 0.001 m, length unit mm), and the
object transforms are identity, so Blender's coordinates are the project frame: +x front,
+y left, +z up. Bones:

* `Size-Bendy` (parent): head at the concha, pointing +y with roll 0, so its pose axes are the
  project axes; it moves, rotates and scales (anisotropically) the whole pinna.
* per curve `<Curve>-Start` and `<Curve>-End` control bones, children of the parent, at the two
  ends of the curve and pointing along its tangent (their Z axis along the surface normal);
* per curve `<Curve>-Bendy`: a B-Bone from start to end, child of its start bone, stretched to
  its end bone, with both handles of type TANGENT driven by the control bones, so rotating a
  control bone flexes the curve.
"""
from __future__ import annotations

import numpy as np

from .deformation import RigGeometry
from .errors import PpmError

MESH_OBJECT = "PPM_Pinna"
ARMATURE_OBJECT = "PPM_Armature"
PARENT_BONE_LENGTH_MM = 10.0
CONTROL_BONE_LENGTH_MM = 4.0


def _bpy():
    try:
        import bpy  # noqa: PLC0415  (Blender is heavy: load it when a rig is built)
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise PpmError("bpy (Blender as a Python module, Python 3.11) is needed for the PPM rig: pip install bpy") from exc
    return bpy


def reset_blender() -> None:
    """Empty Blender's scene (one PPM per process) and set millimetre units."""
    bpy = _bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 0.001
    scene.unit_settings.length_unit = "MILLIMETERS"


def _surface_normal(normals: np.ndarray, vertex_ids: np.ndarray) -> np.ndarray:
    normal = normals[vertex_ids].mean(axis=0)
    return normal / np.linalg.norm(normal)


def build_rig(vertices_mm: np.ndarray, faces: np.ndarray, vertex_normals: np.ndarray, rig: RigGeometry,
              shape_key_ranges: dict[str, tuple[float, float]], bbone_segments: int = 8):
    """Create the mesh and armature objects in the current (empty) Blender scene.

    Parameters
    ----------
    vertices_mm : (n, 3) float
        Template vertices in mm, project frame.
    faces : (m, 3) int
        Template triangles.
    vertex_normals : (n, 3) float
        Unit outward normals of the template, used to roll the bones.
    rig : RigGeometry
        Bones, weights and shape-key offsets from :func:`ppm.deformation.rig_geometry`.
    shape_key_ranges : dict
        Shape-key name -> (lower, upper) weight range (slider limits in Blender).

    Returns
    -------
    (bpy.types.Object, bpy.types.Object)
        The mesh object and the armature object.
    """
    bpy = _bpy()
    scene = bpy.context.scene

    mesh = bpy.data.meshes.new(MESH_OBJECT)
    mesh.from_pydata(np.asarray(vertices_mm, np.float64).tolist(), [], np.asarray(faces).tolist())
    mesh.update()
    mesh_object = bpy.data.objects.new(MESH_OBJECT, mesh)
    armature = bpy.data.armatures.new(ARMATURE_OBJECT)
    armature.display_type = "BBONE"
    armature_object = bpy.data.objects.new(ARMATURE_OBJECT, armature)
    scene.collection.objects.link(mesh_object)
    scene.collection.objects.link(armature_object)
    armature_object.show_in_front = True

    # --- bones (edit mode) ---
    bpy.context.view_layer.objects.active = armature_object
    bpy.ops.object.mode_set(mode="EDIT")
    parent_name = rig.weight_names[-1]
    parent = armature.edit_bones.new(parent_name)
    parent.head = rig.parent_head_mm
    parent.tail = rig.parent_head_mm + np.array([0.0, PARENT_BONE_LENGTH_MM, 0.0])
    parent.roll = 0.0
    parent.use_deform = True
    for curve in rig.curves:
        normal = _surface_normal(vertex_normals, curve.path)
        start = armature.edit_bones.new(f"{curve.name}-Start")
        start.head, start.tail = curve.head_mm, curve.head_mm + CONTROL_BONE_LENGTH_MM * curve.tangent_start
        end = armature.edit_bones.new(f"{curve.name}-End")
        end.head, end.tail = curve.tail_mm, curve.tail_mm + CONTROL_BONE_LENGTH_MM * curve.tangent_end
        bendy = armature.edit_bones.new(f"{curve.name}-Bendy")
        bendy.head, bendy.tail = curve.head_mm, curve.tail_mm
        for bone in (start, end, bendy):
            bone.align_roll(normal)
        for bone in (start, end):
            bone.parent = parent
            bone.use_deform = False
        bendy.parent = start
        bendy.use_deform = True
        bendy.bbone_segments = bbone_segments
        bendy.bbone_mapping_mode = "CURVED"
        bendy.bbone_handle_type_start = "TANGENT"
        bendy.bbone_handle_type_end = "TANGENT"
        bendy.bbone_custom_handle_start = start
        bendy.bbone_custom_handle_end = end
    bpy.ops.object.mode_set(mode="POSE")
    for curve in rig.curves:
        bendy = armature_object.pose.bones[f"{curve.name}-Bendy"]
        stretch = bendy.constraints.new("STRETCH_TO")
        stretch.target = armature_object
        stretch.subtarget = f"{curve.name}-End"
        stretch.rest_length = float(np.linalg.norm(curve.tail_mm - curve.head_mm))
        stretch.volume = "NO_VOLUME"
    for pose_bone in armature_object.pose.bones:
        pose_bone.rotation_mode = "ZYX"
    bpy.ops.object.mode_set(mode="OBJECT")

    # --- vertex weights ---
    for column, name in enumerate(rig.weight_names):
        group = mesh_object.vertex_groups.new(name=name)
        weights = rig.weights[:, column]
        for value in np.unique(weights[weights > 0]):
            group.add(np.flatnonzero(weights == value).tolist(), float(value), "REPLACE")
    modifier = mesh_object.modifiers.new("Armature", "ARMATURE")
    modifier.object = armature_object
    modifier.use_vertex_groups = True
    modifier.use_bone_envelopes = False
    mesh_object.parent = armature_object

    # --- shape keys ---
    mesh_object.shape_key_add(name="Basis", from_mix=False)
    base = np.asarray(vertices_mm, np.float64)
    for name, offset in zip(rig.shape_key_names, rig.shape_key_offsets_mm):
        key = mesh_object.shape_key_add(name=name, from_mix=False)
        lower, upper = shape_key_ranges[name]
        key.slider_min, key.slider_max = float(lower), float(upper)
        key.data.foreach_set("co", (base + offset).astype(np.float32).ravel())
        key.value = 0.0
    return mesh_object, armature_object
