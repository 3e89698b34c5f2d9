"""Evaluation grids of a Mesh2HRTF project: where the HRTFs are computed (metres, project frame).

Grids are sets of points with a triangulation used only for bookkeeping (NumCalc needs every node
in an element). Spherical grids are triangulated by their convex hull; planar rings (sagittal
planes) by a fan, which NumCalc accepts as it never integrates over evaluation elements.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from .errors import Mesh2HrtfIoError


@dataclasses.dataclass(frozen=True)
class EvaluationGrid:
    """A named grid: (n, 3) points in metres (+x front, +y left, +z up, origin at the interaural
    centre) and (k, 3) triangles of local point indices."""

    name: str
    points_m: np.ndarray
    faces: np.ndarray

    def __post_init__(self):
        points = np.asarray(self.points_m, dtype=np.float64)
        faces = np.asarray(self.faces, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 3:
            raise Mesh2HrtfIoError(f"grid {self.name!r}: needs at least 3 points as an (n, 3) array")
        if not np.isfinite(points).all():
            raise Mesh2HrtfIoError(f"grid {self.name!r}: points hold NaN or inf")
        used = np.zeros(len(points), dtype=bool)
        used[faces.ravel()] = True
        if not used.all():
            raise Mesh2HrtfIoError(f"grid {self.name!r}: {int((~used).sum())} points belong to no element")
        if not self.name or any(c in self.name for c in " /\\") or self.name.startswith("."):
            raise Mesh2HrtfIoError(f"grid name {self.name!r}: use a plain folder name without spaces or slashes")
        object.__setattr__(self, "points_m", points)
        object.__setattr__(self, "faces", faces)


def spherical_to_cartesian_m(azimuth_deg: np.ndarray, elevation_deg: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
    """SOFA spherical (azimuth 0 = front, 90 = left; elevation 90 = up; metres) to (n, 3) cartesian metres."""
    az, el = np.deg2rad(azimuth_deg), np.deg2rad(elevation_deg)
    return np.stack([radius_m * np.cos(el) * np.cos(az), radius_m * np.cos(el) * np.sin(az),
                     radius_m * np.sin(el)], axis=1)


def _fan(n: int, offset: int = 0) -> np.ndarray:
    return np.stack([np.full(n - 2, offset), offset + np.arange(1, n - 1), offset + np.arange(2, n)], axis=1)


def ring_grid(name: str, points_m: np.ndarray) -> EvaluationGrid:
    """A grid of points along one ring (e.g. a horizontal or sagittal circle), fan-triangulated; a
    convex hull cannot triangulate points that all lie in one plane."""
    points_m = np.asarray(points_m, dtype=np.float64)
    return EvaluationGrid(name, points_m, _fan(len(points_m)))


def sphere_grid(name: str, points_m: np.ndarray) -> EvaluationGrid:
    """A grid of points around the head triangulated by their convex hull (all must lie on it)."""
    points_m = np.asarray(points_m, dtype=np.float64)
    hull = ConvexHull(points_m)
    if len(np.unique(hull.simplices)) != len(points_m):
        raise Mesh2HrtfIoError(f"grid {name!r}: {len(points_m) - len(np.unique(hull.simplices))} points lie inside "
                               "the hull of the others; spherical grids need all points on one convex surface")
    return EvaluationGrid(name, points_m, hull.simplices)


def grid_from_sofa(path: str | os.PathLike, name: str | None = None) -> EvaluationGrid:
    """The source positions of a SOFA file (e.g. the SONICOM 793-point grid) as a grid."""
    import sofar  # noqa: PLC0415

    path = Path(path)
    if not path.is_file():
        raise Mesh2HrtfIoError(f"{path}: no such SOFA file")
    try:
        sofa = sofar.read_sofa(str(path), verify=False)
    except Exception as exc:  # sofar raises several types for broken files
        raise Mesh2HrtfIoError(f"{path}: cannot be read as SOFA ({exc})") from exc
    positions = np.atleast_2d(np.asarray(sofa.SourcePosition, dtype=np.float64))
    kind = str(getattr(sofa, "SourcePosition_Type", "spherical")).lower()
    points = (spherical_to_cartesian_m(positions[:, 0], positions[:, 1], positions[:, 2]) if kind.startswith("spher")
              else positions)
    return sphere_grid(name or path.stem, points)


def sagittal_grid(name: str = "SagittalPlanes", lateral_angles_deg: tuple[float, ...] = (-20.0, 0.0, 20.0),
                  polar_step_deg: float = 2.5, radius_m: float = 1.2) -> EvaluationGrid:
    """Dense rings in sagittal planes (lateral angle φ, polar angle θ from -90 to 270 deg, 0 = front,
    90 = up): x = r cos φ cos θ, y = r sin φ, z = r cos φ sin θ. Each ring is fan-triangulated."""
    if not 0 < polar_step_deg <= 30:
        raise Mesh2HrtfIoError(f"polar_step_deg must be in (0, 30], got {polar_step_deg}")
    polar = np.deg2rad(np.arange(-90.0, 270.0, polar_step_deg))
    rings, faces = [], []
    for lateral_deg in lateral_angles_deg:
        if not -90 < lateral_deg < 90:
            raise Mesh2HrtfIoError(f"lateral angles must lie in (-90, 90) deg, got {lateral_deg}")
        lateral = np.deg2rad(lateral_deg)
        ring = np.stack([radius_m * np.cos(lateral) * np.cos(polar), np.full(len(polar), radius_m * np.sin(lateral)),
                         radius_m * np.cos(lateral) * np.sin(polar)], axis=1)
        faces.append(_fan(len(ring), sum(len(r) for r in rings)))
        rings.append(ring)
    return EvaluationGrid(name, np.concatenate(rings), np.concatenate(faces))


#: Lateral angles (deg) of the sagittal planes of the full grid: every 10 deg from -80 to 80.
FULL_GRID_LATERAL_DEG = tuple(float(a) for a in range(-80, 81, 10))


def full_grid(polar_step_deg: float = 5.0, radius_m: float = 1.2) -> EvaluationGrid:
    """Directions all round the head in the interaural-polar frame: sagittal planes every 10 deg of lateral angle
    (-80 .. 80 deg, which include the -20, 0 and 20 deg planes the localisation model reads), polar angles every
    ``polar_step_deg`` from -90 to 270 deg on each, at ``radius_m``. A new listener's HRTF set is solved on it."""
    return sagittal_grid("InterauralPolar", FULL_GRID_LATERAL_DEG, polar_step_deg, radius_m)



def with_directions_of(grid: EvaluationGrid, extra: EvaluationGrid, tolerance_deg: float = 0.1,
                       name: str | None = None) -> EvaluationGrid:
    """``grid`` with every direction of ``extra`` it lacks (farther than ``tolerance_deg`` from each of its own),
    those at ``extra``'s own distances (e.g. a listener's full grid at 1.2 m with SONICOM's 793 directions at
    1.5 m, so that a comparison with the dataset keeps all of them). The added points are fan-triangulated for the
    bookkeeping only (NumCalc never integrates over evaluation elements)."""
    own = grid.points_m / np.linalg.norm(grid.points_m, axis=1, keepdims=True)
    other = extra.points_m / np.linalg.norm(extra.points_m, axis=1, keepdims=True)
    from scipy.spatial import cKDTree  # noqa: PLC0415

    chord = 2.0 * np.sin(np.deg2rad(tolerance_deg) / 2.0)
    missing = np.flatnonzero(cKDTree(own).query(other)[0] > chord)
    if missing.size == 0:
        return grid
    added = extra.points_m[missing]
    start = len(grid.points_m)
    faces = (_fan(len(added), start) if len(added) >= 3
             else np.array([[start + i, 0, 1] for i in range(len(added))]))  # one or two: tied to the grid's first
    return EvaluationGrid(name or f"{grid.name}And{extra.name}", np.vstack([grid.points_m, added]),
                          np.vstack([grid.faces, faces]))
