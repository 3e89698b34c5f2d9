"""The parametric pinna model (PPM) evaluated by Blender: parameters in, vertices out.

`PinnaModel` builds the rig on a template (see `ppm.rig`), sets the 144 parameters on the pose
bones and shape keys, and reads the deformed vertices from Blender's evaluated depsgraph. Output
vertices are the template plus Blender's displacement,

    X = X0 + (X_blender(p) - X_blender(p_default)),

i.e. the spec's X0 + ΔX_b + ΔX_s, so the default parameters return the template bit for bit
(Blender works in float32; its rest-pose round-off of about 1e-5 mm is removed this way).
Millimetres, project frame (+x front, +y left, +z up). One model per process: building a model
empties Blender's scene.
"""
from __future__ import annotations

import functools
import json
import logging
import os
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import atomic_path
from .deformation import RigGeometry, rig_geometry, rig_layout
from .errors import PpmError
from .landmarks import load_landmarks
from .mesh_io import write_mesh
from .parameters import PinnaParameters, model_layout, parameter_specs
from .rig import ARMATURE_OBJECT, MESH_OBJECT, PARENT_OBJECT, _bpy, build_rig, reset_blender
from .template.store import Template, load_template

log = logging.getLogger(__name__)

#: The shape key that holds a fit's personal-detail layer (ppm.align.detail): weight 0 is the PPM alone, 1 the PPM
#: with the detail. It is not one of the 144 parameters, so a person can still edit the PPM and dial the detail.
DETAIL_KEY = "Personal_detail"


class PinnaModel:
    """The rigged template pinna in Blender.

    Build it with :meth:`from_template` (a template folder, default: the packaged one) or load a
    saved model with :meth:`from_blend`.
    """

    def __init__(self, mesh_object, armature_object, size_object, template_vertices_mm: np.ndarray,
                 faces: np.ndarray, rig: RigGeometry | None = None):
        self._mesh_object = mesh_object
        self._armature_object = armature_object
        self._size_object = size_object
        self.template_vertices_mm = np.asarray(template_vertices_mm, np.float64)
        self.faces = np.asarray(faces, np.int64)
        self.rig = rig
        self._n = len(self.template_vertices_mm)
        self._buffer = np.empty(self._n * 3, dtype=np.float32)
        self._bind_parameters()
        self._current: PinnaParameters | None = None
        self.set_parameters(PinnaParameters.default())
        detail = self._detail_key()
        weight = detail.value if detail is not None else 0.0
        if detail is not None:
            detail.value = 0.0
        self._rest_blender = self._read_evaluated()
        if detail is not None:
            detail.value = weight

    # -------------------------------------------------------------------------------- build
    @classmethod
    def from_template(cls, template: Template | str | os.PathLike | None = None) -> "PinnaModel":
        """Rig a template (a `Template` or a template folder; default: the packaged template)."""
        if not isinstance(template, Template):
            template = load_template(template)
        landmarks = load_landmarks(template)
        names = list(model_layout()["shape_keys"])
        rig = rig_geometry(template.vertices_mm, template.faces, landmarks, names)
        normals = trimesh.Trimesh(template.vertices_mm, template.faces, process=False).vertex_normals
        reset_blender()
        ranges = {name: tuple(bounds) for name, bounds in model_layout()["shape_keys"].items()}
        objects = build_rig(template.vertices_mm, template.faces, normals, rig, ranges, model_layout()["parent_bone"],
                            rig_layout()["bendy"]["segments"])
        return cls(*objects, template.vertices_mm, template.faces, rig)

    @classmethod
    def from_blend(cls, path: str | os.PathLike) -> "PinnaModel":
        """Open a `.blend` written by :meth:`save_blend`; the pose stored in it is kept."""
        path = Path(path)
        if not path.is_file():
            raise PpmError(f"{path}: no such .blend file")
        bpy = _bpy()
        try:
            bpy.ops.wm.open_mainfile(filepath=str(path))
        except RuntimeError as exc:
            raise PpmError(f"{path}: Blender cannot open it ({exc})") from exc
        mesh_object = bpy.data.objects.get(MESH_OBJECT)
        armature_object = bpy.data.objects.get(ARMATURE_OBJECT)
        size_object = bpy.data.objects.get(PARENT_OBJECT)
        if None in (mesh_object, armature_object, size_object) or mesh_object.data.shape_keys is None:
            raise PpmError(f"{path}: holds no PPM (objects {MESH_OBJECT!r} with shape keys, {ARMATURE_OBJECT!r} "
                           f"and {PARENT_OBJECT!r})")
        basis = mesh_object.data.shape_keys.key_blocks["Basis"]
        rest = np.empty(len(basis.data) * 3, np.float32)
        basis.data.foreach_get("co", rest)
        faces = np.empty(len(mesh_object.data.polygons) * 3, np.int64)
        mesh_object.data.polygons.foreach_get("vertices", faces)
        stored = cls._stored_parameters(mesh_object)
        model = cls(mesh_object, armature_object, size_object, rest.reshape(-1, 3).astype(np.float64),
                    faces.reshape(-1, 3))
        model.set_parameters(stored)
        return model

    # ---------------------------------------------------------------------------- parameters
    def _bind_parameters(self) -> None:
        """Resolve every parameter to the Blender property it drives (once, for speed)."""
        pose = {**{b.name: b for b in self._armature_object.pose.bones},
                **{b.name: b for b in self._size_object.pose.bones}}
        keys = self._mesh_object.data.shape_keys.key_blocks
        self._bone_slots: list[tuple[object, str, int | None]] = []
        self._key_slots: list[object] = []
        for spec in parameter_specs():
            if spec.kind == "shape_key":
                self._key_slots.append(keys[spec.target])
            else:
                self._bone_slots.append((pose[spec.target], spec.kind, spec.axis))
        self._n_bone = len(self._bone_slots)

    def set_parameters(self, params: PinnaParameters) -> None:
        """Put `params` on the pose bones and shape keys (degrees become radians here)."""
        if not isinstance(params, PinnaParameters):
            raise PpmError(f"expected PinnaParameters, got {type(params).__name__}")
        values = params.to_vector()
        radians = np.deg2rad(values)
        for (bone, kind, axis), value, angle in zip(self._bone_slots, values[: self._n_bone], radians[: self._n_bone]):
            if kind == "location":
                bone.location[axis] = value
            elif kind == "rotation":
                bone.rotation_euler[axis] = angle
            elif axis is None:  # isotropic scale of a bendy bone
                bone.scale = (value, value, value)
            else:
                bone.scale[axis] = value
        for key, value in zip(self._key_slots, values[self._n_bone:]):
            key.value = value
        self._current = params

    @property
    def parameters(self) -> PinnaParameters:
        """The parameters currently set."""
        return self._current

    def _read_evaluated(self) -> np.ndarray:
        bpy = _bpy()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = self._mesh_object.evaluated_get(depsgraph)
        evaluated.data.vertices.foreach_get("co", self._buffer)
        local = self._buffer.reshape(-1, 3).astype(np.float64)
        world = np.array(evaluated.matrix_world)  # the parent bone's affine map (identity at rest)
        return local @ world[:3, :3].T + world[:3, 3]

    def evaluate(self, params: PinnaParameters | None = None) -> np.ndarray:
        """(n, 3) float64 deformed vertices in mm (project frame) for `params` (default: those set)."""
        if params is not None:
            self.set_parameters(params)
        return self.template_vertices_mm + (self._read_evaluated() - self._rest_blender)

    def folded_faces(self, vertices_mm: np.ndarray) -> np.ndarray:
        """Indices of the faces of a posed pinna (vertices in mm) whose normal turned by more than 90°
        from the template's: folds. The parent bone (rotation <= 25°, positive scales) cannot cause one."""
        tri = np.asarray(vertices_mm, dtype=np.float64)[self.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return np.flatnonzero(np.einsum("ij,ij->i", normals, self.rest_face_normals) < 0.0)

    @functools.cached_property
    def rest_face_normals(self) -> np.ndarray:
        """(faces, 3) unit normals of the template's triangles (outward, project frame)."""
        tri = self.template_vertices_mm[self.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)

    # ------------------------------------------------------------------------ personal detail
    def _detail_key(self):
        return self._mesh_object.data.shape_keys.key_blocks.get(DETAIL_KEY)

    @property
    def detail_weight(self) -> float:
        """The weight of the personal-detail shape key (0 where the model has none)."""
        key = self._detail_key()
        return float(key.value) if key is not None else 0.0

    def set_detail_weight(self, weight: float) -> None:
        """Dial the personal-detail layer in (1) or out (0)."""
        key = self._detail_key()
        if key is None:
            raise PpmError(f"this PPM has no {DETAIL_KEY!r} shape key; add one with set_personal_detail")
        key.value = float(np.clip(weight, 0.0, 1.0))

    def set_personal_detail(self, displacement_mm: np.ndarray, weight: float = 1.0) -> float:
        """Hold ``displacement_mm`` ((n, 3), mm, project frame: the detail of the pose now set) in the shape key
        :data:`DETAIL_KEY` at ``weight``. Shape keys act before the bones, so the offsets are taken back through
        each vertex's bone deformation by Newton steps (its 3x3 Jacobian measured anew at each step by nudging
        every vertex 0.1 mm along each axis), each kept only where it brings the vertex nearer, until the posed
        result matches within 0.1 µm. Where a vertex sits at a kink of its B-bone's map, the goal may lie out of
        its reach: P067's fit keeps six of its 6,820 vertices 0.1-0.37 mm short. Returns the largest mismatch left
        (mm, per coordinate)."""
        displacement_mm = np.asarray(displacement_mm, dtype=np.float64)
        if displacement_mm.shape != (self._n, 3) or not np.isfinite(displacement_mm).all():
            raise PpmError(f"personal detail: expected finite ({self._n}, 3) displacements in mm, "
                           f"got {displacement_mm.shape}")
        key = self._detail_key() or self._mesh_object.shape_key_add(name=DETAIL_KEY, from_mix=False)
        key.slider_min, key.slider_max = 0.0, 1.0
        basis = np.empty(self._n * 3, np.float32)
        self._mesh_object.data.shape_keys.key_blocks["Basis"].data.foreach_get("co", basis)
        basis = basis.reshape(-1, 3).astype(np.float64)
        key.value = 1.0

        def moved_by(offset: np.ndarray) -> np.ndarray:
            key.data.foreach_set("co", (basis + offset).astype(np.float32).ravel())
            return self._read_evaluated()

        zero = np.zeros_like(basis)
        start = moved_by(zero)

        def jacobian_at(offset: np.ndarray, step_mm: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
            here = moved_by(offset)
            jacobian = np.empty((self._n, 3, 3))
            for axis in range(3):
                nudged = offset.copy()
                nudged[:, axis] += step_mm
                jacobian[:, :, axis] = (moved_by(nudged) - here) / step_mm
            return here, jacobian

        # Newton per vertex (the armature moves each vertex by its own position alone), the Jacobian measured anew
        # at each step: B-bone segment weights follow the keyed position, so the map bends and, where a vertex
        # crosses a segment's edge, kinks. A trial step is kept only where it brings the vertex nearer its goal;
        # elsewhere the vertex stays and its trust radius halves (from 1 mm). A vertex left short of its goal
        # starts again from its neighbours' mean offset (the field is smooth, their start lies past the kink).
        def newton(offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            here, jacobian = jacobian_at(offset)
            miss = displacement_mm - (here - start)
            radius = np.ones(self._n)
            for _ in range(40):
                if np.abs(miss).max() < 1e-4:
                    break
                step = (np.linalg.pinv(jacobian) @ miss[..., None])[..., 0]
                length = np.linalg.norm(step, axis=1)
                trial = offset + step * np.minimum(1.0, radius / np.maximum(length, 1e-12))[:, None]
                trial_here, trial_jacobian = jacobian_at(trial)
                trial_miss = displacement_mm - (trial_here - start)
                better = np.linalg.norm(trial_miss, axis=1) < np.linalg.norm(miss, axis=1)
                offset[better], miss[better], jacobian[better] = trial[better], trial_miss[better], trial_jacobian[better]
                radius = np.where(better, np.minimum(2.0 * radius, 1.0), 0.5 * radius)
            return offset, np.linalg.norm(miss, axis=1)

        offset, miss = newton(zero.copy())
        edges = trimesh.Trimesh(self.template_vertices_mm, self.faces, process=False).edges_unique
        for _ in range(3):
            short = miss > 1e-3
            if not short.any():
                break
            good = ~short
            total, count = np.zeros_like(offset), np.zeros(self._n)
            for a, b in ((edges[:, 0], edges[:, 1]), (edges[:, 1], edges[:, 0])):
                use = good[b]
                np.add.at(total, a[use], offset[b[use]])
                np.add.at(count, a[use], 1.0)
            restart = offset.copy()
            reached = short & (count > 0)
            restart[reached] = total[reached] / count[reached, None]
            again, again_miss = newton(restart)
            better = again_miss < miss
            offset[better], miss[better] = again[better], again_miss[better]
        mismatch = float(np.abs(displacement_mm - (moved_by(offset) - start)).max())
        key.value = float(np.clip(weight, 0.0, 1.0))
        return mismatch

    def mesh(self, params: PinnaParameters | None = None) -> trimesh.Trimesh:
        """The deformed pinna as a trimesh (mm, project frame, template vertex order)."""
        return trimesh.Trimesh(self.evaluate(params), self.faces, process=False)

    # ----------------------------------------------------------------------------------- I/O
    @staticmethod
    def _stored_parameters(mesh_object) -> PinnaParameters:
        text = mesh_object.get("ppm_parameters_json")
        if text is None:
            return PinnaParameters.default()
        return PinnaParameters.from_dict(json.loads(text)["parameters"], out_of_range="clip")

    def save_blend(self, path: str | os.PathLike) -> Path:
        """Save the posed rig as a `.blend` (armature and shape keys live), atomically."""
        path = Path(path)
        if path.suffix != ".blend":
            raise PpmError(f"{path}: a Blender file must end in .blend")
        bpy = _bpy()
        self._mesh_object["ppm_parameters_json"] = self._current.to_json()
        bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backups next to outputs
        with atomic_path(path) as tmp:
            tmp.unlink()  # Blender writes the file itself
            bpy.ops.wm.save_as_mainfile(filepath=str(tmp), copy=True, compress=True)
        return path

    def export(self, path: str | os.PathLike, params: PinnaParameters | None = None) -> Path:
        """Write the deformed pinna as PLY, STL or OBJ (by suffix) in mm, project frame, vertex order kept."""
        return write_mesh(path, self.evaluate(params), self.faces)

    def write_parameters(self, path: str | os.PathLike) -> Path:
        """Write the current parameters as CSV or JSON (by suffix)."""
        return self._current.write(path)


def bone_polylines(model: PinnaModel, samples_per_segment: int = 1) -> dict[str, np.ndarray]:
    """Current (posed) centre line of every bone, in mm, project frame.

    Bendy bones give their B-Bone segment positions (head to tail); straight bones give head and
    tail. Useful for drawing the armature.
    """
    bpy = _bpy()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lines = {}
    for obj in (model._size_object, model._armature_object):
        armature = obj.evaluated_get(depsgraph)
        lines.update(_armature_polylines(armature))
    return lines


def _armature_polylines(armature) -> dict[str, np.ndarray]:
    world = np.array(armature.matrix_world)
    lines = {}
    for pose_bone in armature.pose.bones:
        matrix = world @ np.array(pose_bone.matrix)
        segments = pose_bone.bone.bbone_segments
        if segments > 1:
            points = [(matrix @ np.array(pose_bone.bbone_segment_matrix(i, rest=False)))[:3, 3]
                      for i in range(segments + 1)]
        else:
            points = [np.array(pose_bone.head), np.array(pose_bone.tail)]
            points = [(world @ np.r_[p, 1.0])[:3] for p in points]
        lines[pose_bone.name] = np.asarray(points, dtype=np.float64)
    return lines
