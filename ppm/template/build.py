"""Build of the average LEFT pinna template from scanned ears (millimetres, project frame).

Steps: load each crop as a left ear (right ears mirrored y -> -y); cut the reference crop to the
pinna plus a ring of skin and remesh it to about 1 mm edges (or take a given common topology);
register it rigidly, then non-rigidly, onto every scan; average the registered copies (Procrustes
mean); repeat the registration once from that mean so the result owes little to the reference.
"""
from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from pathlib import Path

import numpy as np
import trimesh

from core.atomic import write_text_atomic
from ..errors import PpmError
from ..landmarks import LANDMARKS_NAME
from ..mesh_io import load_left_pinna
from core.progress import Progress
from .register import procrustes_mean, register_onto
from .segment import crop_to_region, pinna_region

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class EarScan:
    """One scanned pinna crop: subject id, which ear, and the PLY path (mm, project frame)."""

    subject: str
    side: str
    path: Path

    @property
    def label(self) -> str:
        return f"{self.subject}_{self.side}"


def discover_scans(data_root: str | Path) -> list[EarScan]:
    """All `<subject>/pinna_{left,right}_crop.ply` under `data_root`, sorted by subject then side."""
    data_root = Path(data_root)
    if not data_root.is_dir():
        raise PpmError(f"{data_root}: no such data folder; point data_root to a folder of <subject>/pinna_left_crop.ply")
    scans = [
        EarScan(sub.name, side, sub / f"pinna_{side}_crop.ply")
        for sub in sorted(p for p in data_root.iterdir() if p.is_dir())
        for side in ("left", "right")
        if (sub / f"pinna_{side}_crop.ply").is_file()
    ]
    if not scans:
        raise PpmError(f"{data_root}: no <subject>/pinna_left_crop.ply or pinna_right_crop.ply found")
    return scans


def remesh_isotropic(mesh: trimesh.Trimesh, edge_mm: float, max_deviation_mm: float = 0.05,
                     iterations: int = 10) -> trimesh.Trimesh:
    """Isotropic remeshing (pymeshlab) to `edge_mm` edges; the open boundary is kept in place."""
    import pymeshlab  # heavy, and must not be imported before bpy in one process

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=mesh.faces))
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_repair_non_manifold_edges()
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, targetlen=pymeshlab.PureValue(edge_mm), maxsurfdist=pymeshlab.PureValue(max_deviation_mm),
        checksurfdist=True, featuredeg=60.0, reprojectflag=True,
    )
    ms.meshing_remove_unreferenced_vertices()
    out = ms.current_mesh()
    result = trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=False)
    return _largest_component(result)


def _largest_component(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    parts = mesh.split(only_watertight=False)
    return max(parts, key=lambda m: len(m.faces)) if len(parts) > 1 else mesh


def reference_topology(scan: EarScan, edge_mm: float, margin_mm: float) -> trimesh.Trimesh:
    """The pinna-plus-skin-ring of one scan, remeshed to `edge_mm`: the common topology."""
    mesh = load_left_pinna(scan.path, scan.side)
    region = pinna_region(mesh, margin_mm=margin_mm)
    return remesh_isotropic(crop_to_region(mesh, region), edge_mm)


def register_to_scans(topology: trimesh.Trimesh, scans: list[EarScan],
                      progress: Progress | None = None) -> tuple[list[np.ndarray], list[dict]]:
    """Register `topology` onto every scan.

    Returns the deformed vertex arrays (same order, mm) and, per scan, the residual distance
    statistics (template vertex to scan surface, mm) and the time taken (s).
    """
    shapes, stats = [], []
    for scan in scans:
        start = time.perf_counter()
        target = load_left_pinna(scan.path, scan.side)
        shapes.append(register_onto(topology, target))
        residual = trimesh.proximity.closest_point(target, shapes[-1])[1]
        stats.append({"scan": scan.label, "median_mm": round(float(np.median(residual)), 3),
                      "p95_mm": round(float(np.percentile(residual, 95)), 3),
                      "seconds": round(time.perf_counter() - start, 1)})
        log.info("registered onto %(scan)s: median %(median_mm).2f mm, p95 %(p95_mm).2f mm, %(seconds).1f s", stats[-1])
        if progress is not None:
            progress.step(scan.label)
    return shapes, stats


def build_template(scans: list[EarScan], *, topology: trimesh.Trimesh | None = None, edge_mm: float = 1.0,
                   margin_mm: float = 6.0, rounds: int = 2) -> tuple[trimesh.Trimesh, list[dict]]:
    """Average LEFT pinna of `scans` on one common topology.

    Parameters
    ----------
    scans : list of EarScan
        The ears to average (already without any subject left out).
    topology : trimesh.Trimesh, optional
        Common topology to reuse (for leave-one-out builds: the default template). Without it the
        first scan is cut and remeshed to `edge_mm`.
    edge_mm, margin_mm : float
        Target edge length and the width of the skin ring kept around the pinna, in mm.
    rounds : int
        Registration rounds; each round starts from the previous mean.

    Returns
    -------
    template : trimesh.Trimesh
        The mean pinna, in mm, in the project frame, with the vertex order of `topology` when one
        is given (otherwise a fresh isotropic remesh of the mean).
    residuals : list of dict
        Per scan, the last round's registration residuals (see :func:`register_to_scans`).
    """
    if not scans:
        raise PpmError("no ear scans to build a template from")
    current = topology if topology is not None else reference_topology(scans[0], edge_mm, margin_mm)
    progress = Progress(rounds * len(scans), "template registrations", log)
    for round_index in range(rounds):
        log.info("round %d/%d: registering %d vertices onto %d scans", round_index + 1, rounds,
                 len(current.vertices), len(scans))
        shapes, residuals = register_to_scans(current, scans, progress)
        current = trimesh.Trimesh(procrustes_mean(shapes), current.faces, process=False)
    if topology is None:
        # a new common topology: remesh the mean once more, so averaging leaves no slivers in creases
        current = remesh_isotropic(current, edge_mm)
    return current, residuals


#: Where the SONICOM-derived scans come from, for the provenance record.
SONICOM_SOURCE = (
    "SONICOM HRTF dataset subjects as prepared for Mesh2HRTF in the public repository 'A Comparative Study "
    "of HRTF Measurements and Simulations Using SONICOM Data' (MIT licence for its code, meshes and "
    "simulated data; SONICOM's own terms also apply)"
)


def build_template_folder(data_root: str | Path, out_dir: str | Path, *, exclude: list[str] | None = None,
                          topology_dir: str | Path | None = None, edge_mm: float = 1.0, margin_mm: float = 6.0,
                          rounds: int = 2, source: str = SONICOM_SOURCE) -> Path:
    """Build a template from every scan under `data_root` except the `exclude`d subjects; write a folder.

    With `topology_dir` (a template folder) its vertex order is reused, so landmarks and bone
    weights defined on it hold for the new template too (leave-one-subject-out builds).
    """
    from .store import Template, load_template, save_template

    exclude = sorted(exclude or [])
    all_scans = discover_scans(data_root)
    unknown = set(exclude) - {scan.subject for scan in all_scans}
    if unknown:
        raise PpmError(f"exclude names subjects not in {data_root}: {sorted(unknown)}")
    scans = [scan for scan in all_scans if scan.subject not in exclude]
    topology = load_template(topology_dir).mesh if topology_dir is not None else None
    start = time.perf_counter()
    mesh, residuals = build_template(scans, topology=topology, edge_mm=edge_mm, margin_mm=margin_mm, rounds=rounds)
    edges = mesh.edges_unique_length
    provenance = {
        "what": "average LEFT pinna with a ring of surrounding skin, millimetres, +x front, +y left, +z up",
        "scans": [{"subject": s.subject, "side": s.side, "file": s.path.name,
                   "sha256": hashlib.sha256(s.path.read_bytes()).hexdigest(),
                   "mirrored_y": s.side == "right"} for s in scans],
        "excluded_subjects": exclude,
        "source_and_licence": source,
        "topology": "reused from " + str(topology_dir) if topology_dir is not None
        else f"remeshed crop of {scans[0].label}; the final mean remeshed once more",
        "settings": {"edge_mm": edge_mm, "margin_mm": margin_mm, "rounds": rounds},
        "registration_residuals": residuals,
        "n_vertices": int(len(mesh.vertices)), "n_faces": int(len(mesh.faces)),
        "edge_median_mm": round(float(np.median(edges)), 3),
        "build_seconds": round(time.perf_counter() - start, 1),
    }
    # float32-representable coordinates: Blender stores float32, so the rig's rest pose is the template exactly
    vertices = np.asarray(mesh.vertices, np.float32).astype(np.float64)
    folder = save_template(out_dir, Template(vertices, np.asarray(mesh.faces), provenance))
    if topology_dir is not None:  # same vertex order, so the landmarks' vertex ids carry over
        landmarks = Path(topology_dir) / LANDMARKS_NAME
        write_text_atomic(folder / LANDMARKS_NAME, landmarks.read_text(encoding="utf-8"))
    return folder
