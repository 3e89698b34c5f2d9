"""Construction of the PPM rig in Blender (bpy): template mesh, armature with B-Bones, shape keys.

Blender units are millimetres (the scene's unit scale is 0.001 m, length unit mm), and the
object transforms are identity, so Blender's coordinates are the project frame: +x front,
+y left, +z up. Bones:

* `Size-Bendy` (parent), the only bone of the armature object `PPM_Size`: head at the concha,
  pointing +y with roll 0, so its pose axes are the project axes. The curve armature and the mesh
  are children of this bone (object parenting), so it moves, rotates and scales (anisotropically)
  the whole deformed pinna as one affine map, exactly, with no shear inside the B-Bones.
* in the armature object `PPM_Armature`: a static root bone `Curves-Root` that holds the weight no
  bendy bone takes, and per curve `<Curve>-Start` and `<Curve>-End` control bones at the two ends
  of the curve, pointing along its tangent (their Z axis along the surface normal);
* per curve `<Curve>-Bendy`: a B-Bone from start to end, child of the parent, its head held on
  the start bone (Copy Location) and its tail on the end bone (Stretch To), with both handles of
  type TANGENT driven by the control bones, so rotating a control bone flexes the curve without
  twisting it; its isotropic scale widens or narrows the structure around the curve.
"""
from __future__ import annotations

import numpy as np

from .deformation import RigGeometry
from .errors import PpmError

MESH_OBJECT = "PPM_Pinna"
ARMATURE_OBJECT = "PPM_Armature"
PARENT_OBJECT = "PPM_Size"
ROOT_BONE = "Curves-Root"
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
              shape_key_ranges: dict[str, tuple[float, float]], parent_bone: str, bbone_segments: int = 8):
    """Create the mesh and the two armature objects in the current (empty) Blender scene.

    Parameters
    ----------
    vertices_mm : (n, 3) float
        Template vertices in mm, project frame.
    faces : (m, 3) int
        Template triangles.
    vertex_normals : (n, 3) float
        Unit outward normals of the template, used to roll the bones.
    rig : RigGeometry
        Bones, weights and shape-key offsets from :func:`ppm.deformation.rig_geometry`; its last
        weight column is the remainder, held by the static root bone.
    shape_key_ranges : dict
        Shape-key name -> (lower, upper) weight range (slider limits in Blender).
    parent_bone : str
        Name of the parent bone (`Size-Bendy`).

    Returns
    -------
    (bpy.types.Object, bpy.types.Object, bpy.types.Object)
        The mesh object, the curve armature object and the parent armature object.
    """
    bpy = _bpy()
    from mathutils import Matrix  # noqa: PLC0415  (ships with bpy)

    scene = bpy.context.scene
    mesh = bpy.data.meshes.new(MESH_OBJECT)
    mesh.from_pydata(np.asarray(vertices_mm, np.float64).tolist(), [], np.asarray(faces).tolist())
    mesh.update()
    mesh_object = bpy.data.objects.new(MESH_OBJECT, mesh)
    armature = bpy.data.armatures.new(ARMATURE_OBJECT)
    armature.display_type = "BBONE"
    armature_object = bpy.data.objects.new(ARMATURE_OBJECT, armature)
    size_armature = bpy.data.armatures.new(PARENT_OBJECT)
    size_object = bpy.data.objects.new(PARENT_OBJECT, size_armature)
    for obj in (mesh_object, armature_object, size_object):
        scene.collection.objects.link(obj)
    armature_object.show_in_front = size_object.show_in_front = True

    # --- the parent bone, alone in its armature ---
    bpy.context.view_layer.objects.active = size_object
    bpy.ops.object.mode_set(mode="EDIT")
    parent = size_armature.edit_bones.new(parent_bone)
    parent.head = rig.parent_head_mm
    parent.tail = rig.parent_head_mm + np.array([0.0, PARENT_BONE_LENGTH_MM, 0.0])
    parent.roll = 0.0
    parent.use_deform = False
    bpy.ops.object.mode_set(mode="POSE")
    size_object.pose.bones[parent_bone].rotation_mode = "ZYX"
    bpy.ops.object.mode_set(mode="OBJECT")

    # --- curve bones (edit mode) ---
    bpy.context.view_layer.objects.active = armature_object
    bpy.ops.object.mode_set(mode="EDIT")
    root = armature.edit_bones.new(rig.weight_names[-1])
    root.head = rig.parent_head_mm
    root.tail = rig.parent_head_mm + np.array([0.0, 0.5 * PARENT_BONE_LENGTH_MM, 0.0])
    root.use_deform = True
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
            bone.parent = root
        start.use_deform = end.use_deform = False
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
        follow = bendy.constraints.new("COPY_LOCATION")  # head follows the start bone's head
        follow.target = armature_object
        follow.subtarget = f"{curve.name}-Start"
        stretch = bendy.constraints.new("STRETCH_TO")  # tail follows the end bone's head
        stretch.target = armature_object
        stretch.subtarget = f"{curve.name}-End"
        stretch.rest_length = float(np.linalg.norm(curve.tail_mm - curve.head_mm))
        stretch.volume = "NO_VOLUME"
        for constraint in (follow, stretch):  # armature space, so the parent's scale cannot leak in
            constraint.owner_space = constraint.target_space = "POSE"
    for pose_bone in armature_object.pose.bones:
        pose_bone.rotation_mode = "ZYX"
    bpy.ops.object.mode_set(mode="OBJECT")

    # --- the curve armature and the mesh hang on the parent bone (rest: identity world matrix) ---
    # Blender hangs a bone's children on its tail: undo that rest frame so the children start at identity
    rest_bone = size_object.data.bones[parent_bone]
    bone_tail_frame = size_object.matrix_world @ rest_bone.matrix_local @ Matrix.Translation((0.0, rest_bone.length, 0.0))
    for child in (armature_object, mesh_object):
        child.parent = size_object
        child.parent_type = "BONE"
        child.parent_bone = parent_bone
        child.matrix_parent_inverse = bone_tail_frame.inverted()

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

    # --- shape keys ---
    mesh_object.shape_key_add(name="Basis", from_mix=False)
    base = np.asarray(vertices_mm, np.float64)
    for name, offset in zip(rig.shape_key_names, rig.shape_key_offsets_mm):
        key = mesh_object.shape_key_add(name=name, from_mix=False)
        lower, upper = shape_key_ranges[name]
        key.slider_min, key.slider_max = float(lower), float(upper)
        key.data.foreach_set("co", (base + offset).astype(np.float32).ravel())
        key.value = 0.0
    return mesh_object, armature_object, size_object
