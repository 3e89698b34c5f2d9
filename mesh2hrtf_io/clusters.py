"""NumCalc's multilevel cluster tree, predicted from the mesh, and the level-0 cluster size we write.

NumCalc 1.2.4 (``NC_EstimateNumLevelsMLFMM``) works with the mean element size ℓ = sqrt(mean element area):
the finest clusters must be at least 5ℓ across (``clu_l_min``); the level-0 cluster size L0 is taken from
NC.inp ("Main Parameters II", 4th value, metres) or, when that is 0, derived as N^{1/4} / sqrt(0.9) · ℓ
for N elements; the number of levels is round(log2(L0 / 5ℓ)) + 1 and the finest clusters are
L0 / 2^(levels - 1) across. So by default the tree depends on N alone: below ~32,400 elements a head
gets 2 levels with finest clusters ~7ℓ across, above it 3 levels with ~3.5ℓ. A graded head (1 mm at the
pinna, 6 mm far away) has ℓ ≈ 2.3 mm, so its finest clusters near the pinna hold hundreds of 1 mm
elements, and the near-field matrix (dense between neighbouring finest clusters) dominates the step.

We choose L0 so that the finest clusters are as small as NumCalc allows (2^-0.45 · 5ℓ ≈ 3.7ℓ, just past the
rounding edge) at a chosen number of levels.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

MIN_CLUSTER_ELEMENTS = 5.0      # NumCalc: finest clusters at least 5 mean element lengths across
ROOT_CLUSTER_FACTOR = 0.9       # NumCalc: ~0.9 sqrt(N) root clusters
ROUNDING_MARGIN = 0.05          # L0 sits this far (in octaves) past NumCalc's rounding edge


@dataclasses.dataclass(frozen=True)
class ClusterTree:
    """NumCalc's tree for one mesh: level-0 cluster size (m; as written, 0 = NumCalc's default), the size
    NumCalc uses, levels, finest cluster size (m), mean element length ℓ (m) and the element count."""

    written_m: float
    level0_m: float
    levels: int
    finest_m: float
    element_length_m: float
    n_elements: int

    def as_dict(self) -> dict:
        return {key: (round(value, 6) if isinstance(value, float) else value)
                for key, value in dataclasses.asdict(self).items()}


def mean_element_length_m(vertices_m: np.ndarray, faces: np.ndarray) -> float:
    """sqrt of the mean triangle area (m), as NumCalc's averageElementArea_."""
    a, b, c = (vertices_m[faces[:, i]] for i in range(3))
    return float(math.sqrt(np.mean(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1))))


def cluster_tree(n_elements: int, element_length_m: float, written_m: float = 0.0) -> ClusterTree:
    """The tree NumCalc 1.2.4 builds for a mesh of ``n_elements`` with mean element length ℓ and the level-0
    size ``written_m`` of NC.inp (0: its default). Raises ValueError where NumCalc would stop."""
    smallest = MIN_CLUSTER_ELEMENTS * element_length_m
    if written_m > 0:
        if written_m < smallest:
            raise ValueError(f"a level-0 cluster size of {written_m:g} m is below NumCalc's smallest allowed "
                             f"{smallest:g} m (5 mean element lengths)")
        level0 = written_m
    else:
        root_clusters = max(math.sqrt(n_elements) * ROOT_CLUSTER_FACTOR, 25.0)
        level0 = math.sqrt(n_elements / root_clusters) * element_length_m
    octaves = math.log2(level0 / smallest)
    levels = int(octaves)
    if octaves - levels > 0.5:
        levels += 1
    levels = max(levels + 1, 1)
    return ClusterTree(float(written_m), level0, levels, level0 / 2 ** (levels - 1), element_length_m, int(n_elements))


def fine_cluster_size_m(n_elements: int, element_length_m: float, levels: int = 3) -> float:
    """Level-0 size (m) that gives ``levels`` levels with the smallest finest clusters NumCalc allows."""
    if levels < 2:
        raise ValueError("give at least 2 levels (one level is NumCalc's single-level FMM)")
    return MIN_CLUSTER_ELEMENTS * element_length_m * 2 ** (levels - 1.5 + ROUNDING_MARGIN)


AUTO_FROM_ELEMENTS = 10000      # smaller meshes keep NumCalc's default (measured only on 27k-39k heads)
AUTO_LEVELS = 3                 # 3 levels beat 4 on a 30.6k-element graded head (128 s vs 146 s at 1 kHz)


def chosen_cluster_size_m(n_elements: int, element_length_m: float) -> float:
    """'auto': the level-0 size (m) that gives 3 levels with the smallest finest clusters, for meshes of at
    least 10,000 elements; 0 (NumCalc's default) for smaller ones."""
    if n_elements < AUTO_FROM_ELEMENTS:
        return 0.0
    return fine_cluster_size_m(n_elements, element_length_m, AUTO_LEVELS)


def planned_cluster_tree(vertices_m: np.ndarray, faces: np.ndarray, setting: float | str = "auto",
                         source: str = "mesh") -> ClusterTree:
    """The tree NumCalc will build for a mesh (metres) with the level-0 setting 'auto' or a size in metres
    (0 = NumCalc's default); a size below NumCalc's smallest is an error naming ``source``."""
    from .errors import Mesh2HrtfIoError  # noqa: PLC0415

    n_elements, length = len(faces), mean_element_length_m(vertices_m, faces)
    if setting == "auto":
        written = chosen_cluster_size_m(n_elements, length)
    elif isinstance(setting, (int, float)) and math.isfinite(setting) and setting >= 0:
        written = float(setting)
    else:
        raise Mesh2HrtfIoError(f"{source}: the NumCalc level-0 cluster size must be 'auto' or a size in metres "
                               f">= 0 (0 = NumCalc's default), got {setting!r}")
    try:
        return cluster_tree(n_elements, length, round(written, 4) if written else 0.0)
    except ValueError as exc:
        raise Mesh2HrtfIoError(f"{source}: {exc}; use 'auto' or a larger size") from exc
