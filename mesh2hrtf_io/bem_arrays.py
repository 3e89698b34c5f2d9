"""The Burton–Miller solve as whole-array operations, the same code on NumPy (CPU) and CuPy (GPU).

Everything the embedded solver computes per frequency is written here with array operations of one namespace
``xp`` (NumPy or CuPy), so that the GPU path has a CPU twin that runs the very same arithmetic:

- the system matrix ``i/k W - K + M/2`` on P1 (W hypersingular, K double layer, M the P1 Gram matrix), far element
  pairs with bempp-cl's triangle Gauss rule, touching pairs (a shared vertex, edge or the element itself) with its
  singular (Sauter–Schwab) rule, exactly the quadrature of :mod:`mesh2hrtf_io.burton_miller`;
- the right-hand side of a source (single layer and adjoint double layer of the ear's DP0 velocity);
- the pressure at the evaluation points (double layer potential of P1, single layer potential of the ear's DP0).

Conventions as in :mod:`mesh2hrtf_io.bem`: SI units (metres), e^{-iωt}, G = e^{ikr} / (4πr), normals out of the
head. The frequency-independent geometry (:class:`SurfaceArrays`) is taken from bempp-cl once, on the CPU, and can
be saved to and loaded from an ``.npz`` file, so the GPU side needs neither bempp-cl nor any mesh library.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

INV_4PI = 1.0 / (4.0 * np.pi)


@dataclasses.dataclass(frozen=True)
class SurfaceArrays:
    """Frequency-independent arrays of a P1 surface (metres, NumPy).

    Per element (E of them), Gauss rule with q points: ``points`` (E, q, 3), ``weights`` (E, q) Gauss weight times
    the integration element (m^2), ``normals`` (E, 3) outward, ``curls`` (E, 3 shape functions, 3) surface curls of
    the P1 shape functions (1/m), ``corners`` (E, 3, 3), ``integration_elements`` (E,) (twice the area, m^2),
    ``dofs``/``multipliers`` (E, 3) the P1 degrees of freedom and signs; ``shape`` (q, 3) the P1 shape functions at
    the Gauss points. Touching pairs (T): ``touch_test``/``touch_trial`` (T,) and per quadrature group (pairs that
    share one point set of the singular rule) ``group_of_pair`` (T,), ``group_test_points``/``group_trial_points``
    (G, 2, c) reference coordinates, ``group_weights`` (G, c), ``group_counts`` (G,) (c the largest count; a group
    uses its first ``group_counts[g]``)."""

    points: np.ndarray
    weights: np.ndarray
    normals: np.ndarray
    curls: np.ndarray
    corners: np.ndarray
    integration_elements: np.ndarray
    dofs: np.ndarray
    multipliers: np.ndarray
    shape: np.ndarray
    dof_count: int
    touch_test: np.ndarray
    touch_trial: np.ndarray
    group_of_pair: np.ndarray
    group_test_points: np.ndarray
    group_trial_points: np.ndarray
    group_weights: np.ndarray
    group_counts: np.ndarray

    @property
    def n_elements(self) -> int:
        return int(self.points.shape[0])

    def save(self, path: str | os.PathLike) -> None:
        """Write all arrays to one compressed ``.npz`` file (atomically)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".part.npz")
        np.savez_compressed(tmp, **{field.name: np.asarray(getattr(self, field.name)) for field in dataclasses.fields(self)})
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SurfaceArrays":
        with np.load(path) as data:
            values = {field.name: data[field.name] for field in dataclasses.fields(cls)}
        values["dof_count"] = int(values["dof_count"])
        return cls(**values)


def surface_arrays(grid, p1, regular_order: int, singular_order: int) -> SurfaceArrays:
    """The arrays of a bempp-cl grid and its P1 space, with the quadrature orders of the embedded solver."""
    from . import burton_miller  # noqa: PLC0415

    return from_geometry(burton_miller.far_field_geometry(grid, p1, regular_order),
                         burton_miller.singular_pairs(grid, p1, singular_order))


def from_geometry(far, touching) -> SurfaceArrays:
    """The arrays of a :class:`burton_miller.FarFieldGeometry` and its :class:`burton_miller.SingularPairs`."""
    keys = np.stack([touching.test_offsets, touching.trial_offsets, touching.weight_offsets, touching.counts], axis=1)
    unique_keys, group_of_pair = np.unique(keys, axis=0, return_inverse=True)
    width = int(unique_keys[:, 3].max())
    groups = len(unique_keys)
    test_points = np.zeros((groups, 2, width))
    trial_points = np.zeros((groups, 2, width))
    group_weights = np.zeros((groups, width))
    for g, (test_offset, trial_offset, weight_offset, count) in enumerate(unique_keys):
        test_points[g, :, :count] = touching.test_points[:, test_offset:test_offset + count]
        trial_points[g, :, :count] = touching.trial_points[:, trial_offset:trial_offset + count]
        group_weights[g, :count] = touching.weights[weight_offset:weight_offset + count]
    return SurfaceArrays(
        points=far.points, weights=far.weights, normals=far.normals, curls=far.curls, corners=far.corners,
        integration_elements=far.integration_elements, dofs=far.dofs, multipliers=far.multipliers, shape=far.shape,
        dof_count=far.dof_count, touch_test=touching.test_elements, touch_trial=touching.trial_elements,
        group_of_pair=group_of_pair.astype(np.int64).ravel(), group_test_points=test_points,
        group_trial_points=trial_points, group_weights=group_weights, group_counts=unique_keys[:, 3].astype(np.int64))


@dataclasses.dataclass
class ArrayBackend:
    """An array namespace and what the solve needs besides it: NumPy with SciPy, or CuPy with cupyx."""

    name: str
    xp: Any
    sparse: Any
    lu_factor: Any
    lu_solve: Any

    def asarray(self, array, dtype=None):
        return self.xp.asarray(array, dtype=dtype)

    def to_host(self, array) -> np.ndarray:
        return array.get() if hasattr(array, "get") else np.asarray(array)

    def synchronize(self) -> None:
        if self.name == "cupy":
            self.xp.cuda.Stream.null.synchronize()


def numpy_backend() -> ArrayBackend:
    """The CPU twin: NumPy, SciPy's sparse matrices and LAPACK's LU."""
    import scipy.linalg  # noqa: PLC0415
    import scipy.sparse  # noqa: PLC0415

    return ArrayBackend("numpy", np, scipy.sparse,
                        lambda a: scipy.linalg.lu_factor(a, overwrite_a=True, check_finite=False),
                        lambda factors, b: scipy.linalg.lu_solve(factors, b, check_finite=False))


def cupy_backend() -> ArrayBackend:
    """The GPU: CuPy, cupyx's sparse matrices and cuSOLVER's LU (raises ImportError without CuPy)."""
    import cupy  # noqa: PLC0415
    import cupyx.scipy.linalg  # noqa: PLC0415
    import cupyx.scipy.sparse  # noqa: PLC0415

    return ArrayBackend("cupy", cupy, cupyx.scipy.sparse,
                        lambda a: cupyx.scipy.linalg.lu_factor(a, overwrite_a=True, check_finite=False),
                        lambda factors, b: cupyx.scipy.linalg.lu_solve(factors, b, check_finite=False))


class DeviceSurface:
    """A :class:`SurfaceArrays` moved to a backend's memory, with the scatter matrices of the P1 assembly."""

    def __init__(self, surface: SurfaceArrays, backend: ArrayBackend):
        self.surface = surface
        self.backend = backend
        xp = backend.xp
        s = surface
        self.n = s.dof_count
        self.E = s.n_elements
        self.points = xp.asarray(s.points)
        self.weights = xp.asarray(s.weights)
        self.normals = xp.asarray(s.normals)
        self.curls = xp.asarray(s.curls)
        self.corners = xp.asarray(s.corners)
        self.integration_elements = xp.asarray(s.integration_elements)
        self.shape = xp.asarray(s.shape)
        self.multipliers = xp.asarray(s.multipliers)
        self.dofs = xp.asarray(s.dofs)
        # (E * 3, n) sparse: local shape function (element b, j) -> its global P1 degree of freedom, with its sign
        self.local_to_global = self._scatter(np.arange(3 * s.n_elements), s.dofs.ravel(), s.multipliers.ravel(),
                                             (3 * s.n_elements, s.dof_count))
        self.touch_test = xp.asarray(s.touch_test)
        self.touch_trial = xp.asarray(s.touch_trial)
        # touching pairs sorted by test element, to mark them in each chunk of test elements
        order = np.argsort(s.touch_test, kind="stable")
        self._touch_sorted_test = s.touch_test[order]
        self._touch_sorted_trial = s.touch_trial[order]

    def _scatter(self, rows, columns, values, shape):
        matrix = self.backend.sparse.coo_matrix((self.backend.xp.asarray(values, dtype=np.complex128),
                                                 (self.backend.xp.asarray(rows), self.backend.xp.asarray(columns))),
                                                shape=shape)
        return matrix.tocsr()

    def touching_in(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """(test, trial) of the touching pairs whose test element lies in [start, stop) (host arrays)."""
        lo, hi = np.searchsorted(self._touch_sorted_test, [start, stop])
        return self._touch_sorted_test[lo:hi], self._touch_sorted_trial[lo:hi]


#: GPU cost model, measured on an NVIDIA H200 (benchmarks/gpu_solve.py, SONICOM P143): the assembly takes
#: 5.4e-9 s per element pair (31,466 elements: 5.33 s; 27,666: 4.13 s), cuSOLVER's complex LU 8e-14 s per n^3
#: (n = 15,735: 0.31 s), the rest (right-hand sides, potentials at 793 points) about 0.1 s.
GPU_SECONDS_PER_ELEMENT_PAIR = 5.4e-9
GPU_LU_SECONDS_PER_CUBE = 8.0e-14
#: Work arrays of the GPU assembly: up to this many bytes (more buys no speed: the chunks are already large)
GPU_WORK_BUDGET_BYTES = 24e9
#: The smallest work budget worth starting with (bytes): below it the chunks are too small to be efficient
GPU_MIN_WORK_BYTES = 2e9


def gpu_memory_needed_bytes(n_dofs: int, work_bytes: float = GPU_MIN_WORK_BYTES) -> float:
    """GPU memory (bytes) a solve needs: the dense system and its column-major copy for the LU (16 n^2 each) plus
    the assembly's work arrays."""
    return 2 * 16.0 * n_dofs ** 2 + work_bytes


def gpu_work_budget(n_dofs: int, source: str = "") -> float:
    """Bytes the GPU assembly may use for its work arrays, from the memory free now; a clear error when the head
    does not fit."""
    import cupy  # noqa: PLC0415

    pool = cupy.get_default_memory_pool()
    free, total = cupy.cuda.Device().mem_info
    return work_budget_for(n_dofs, free + pool.free_bytes(), total, source)


def work_budget_for(n_dofs: int, free_bytes: float, total_bytes: float, source: str = "") -> float:
    """Bytes for the assembly's work arrays with ``free_bytes`` of GPU memory free, or a clear error when the dense
    system and the smallest useful work budget do not fit."""
    from .errors import Mesh2HrtfIoError  # noqa: PLC0415

    fixed = gpu_memory_needed_bytes(n_dofs, 0.0)
    if free_bytes < gpu_memory_needed_bytes(n_dofs):
        raise Mesh2HrtfIoError(
            f"{source or 'the head'}: {n_dofs} vertices need {gpu_memory_needed_bytes(n_dofs) / 1e9:.1f} GB on the GPU "
            f"(the dense system twice, {fixed / 1e9:.1f} GB, and {GPU_MIN_WORK_BYTES / 1e9:.0f} GB of work arrays), "
            f"but {free_bytes / 1e9:.1f} of {total_bytes / 1e9:.1f} GB are free; use a coarser mesh, NumCalc "
            "(hrtf.solver: numcalc), or a GPU with more memory")
    return float(min(GPU_WORK_BUDGET_BYTES, 0.8 * (free_bytes - fixed)))


def gpu_seconds_per_frequency(n_dofs: int, n_elements: int) -> float:
    """Predicted GPU seconds of one frequency (all sources), :data:`GPU_SECONDS_PER_ELEMENT_PAIR`."""
    return GPU_SECONDS_PER_ELEMENT_PAIR * n_elements ** 2 + GPU_LU_SECONDS_PER_CUBE * n_dofs ** 3 + 0.1


def default_chunk(n_elements: int, q: int, budget_bytes: float) -> int:
    """Test elements per chunk of the far-pair assembly so that its ~14 complex (chunk, q, E, q) work arrays fit
    in ``budget_bytes``."""
    per_element = 14 * 16.0 * q * n_elements * q
    return int(max(1, min(n_elements, budget_bytes // per_element)))


def far_pairs(dev: DeviceSurface, wavenumber: float, coupling: complex, chunk: int | None = None,
              budget_bytes: float = 0.5e9):
    """Dense (n, n) ``coupling * W - K`` over the element pairs that share no vertex (bempp-cl's Gauss rule of the
    surface). Chunks of test elements against every trial element; touching pairs are masked out."""
    xp = dev.backend.xp
    E, q = dev.points.shape[:2]
    chunk = chunk or default_chunk(E, q, budget_bytes)
    k = float(wavenumber)
    matrix = xp.zeros((dev.n, dev.n), np.complex128)
    y = dev.points  # (E, q, 3)
    normals_b = dev.normals
    for start in range(0, E, chunk):
        stop = min(E, start + chunk)
        ca = stop - start
        x = dev.points[start:stop]
        d0 = y[None, None, :, :, 0] - x[:, :, None, None, 0]  # (ca, q, E, q): y - x
        d1 = y[None, None, :, :, 1] - x[:, :, None, None, 1]
        d2 = y[None, None, :, :, 2] - x[:, :, None, None, 2]
        touch_test, touch_trial = dev.touching_in(start, stop)
        far = xp.ones((ca, E), np.float64)
        far[xp.asarray(touch_test - start), xp.asarray(touch_trial)] = 0.0
        far4 = far[:, None, :, None]
        r = xp.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * far4 + (1.0 - far4)  # touching pairs: r = 1, weight 0 below
        kr = k * r
        green = xp.exp(1j * kr) * (INV_4PI / r)
        green *= (dev.weights[start:stop, :, None, None] * dev.weights[None, None, :, :]) * far4
        green_sum = green.sum(axis=(1, 3))  # (ca, E)
        gradient = green * (1j * kr - 1.0) / (r * r)
        normal_derivative = (d0 * normals_b[None, None, :, None, 0] + d1 * normals_b[None, None, :, None, 1]
                             + d2 * normals_b[None, None, :, None, 2])
        normal_product = dev.normals[start:stop] @ normals_b.T  # (ca, E)
        kernel = (-coupling * k * k) * normal_product[:, None, :, None] * green - gradient * normal_derivative
        del d0, d1, d2, r, kr, green, gradient, normal_derivative
        block = _contract_shapes(xp, kernel, dev.shape)  # (ca, 3, E, 3)
        del kernel
        curl_product = xp.einsum("aic,bjc->aibj", dev.curls[start:stop], dev.curls)
        block += coupling * curl_product * green_sum[:, None, :, None]
        _scatter_block(dev, matrix, block, start, stop)
    return matrix


def _contract_shapes(xp, kernel, shape):
    """sum_pq shape[p, i] kernel[a, p, b, q] shape[q, j] -> (a, i, b, j)."""
    ca, q, E, _ = kernel.shape
    right = (kernel.reshape(ca * q * E, q) @ shape).reshape(ca, q, E * 3)  # (a, p, b j)
    left = xp.einsum("pi,apm->aim", shape, right)  # (a, i, b j)
    return left.reshape(ca, 3, E, 3)


def _scatter_block(dev: DeviceSurface, matrix, block, start: int, stop: int) -> None:
    """Add a (ca, 3, E, 3) block of test elements [start, stop) x all trial elements into the dense matrix by two
    sparse products (local shape functions -> global P1 degrees of freedom)."""
    xp = dev.backend.xp
    ca = stop - start
    rows = dev.surface.dofs[start:stop].ravel()
    signs = dev.surface.multipliers[start:stop].ravel()
    flat = block.reshape(ca * 3, dev.E * 3)
    # columns: (n, E*3) @ (E*3, ca*3) -> the chunk's local test functions against global columns
    columns = (dev.local_to_global.T @ flat.T).T  # (ca*3, n)
    unique_rows, inverse = np.unique(rows, return_inverse=True)
    gather = dev.backend.sparse.coo_matrix(
        (xp.asarray(signs, dtype=np.complex128), (xp.asarray(inverse.ravel()), xp.asarray(np.arange(ca * 3)))),
        shape=(len(unique_rows), ca * 3)).tocsr()
    matrix[xp.asarray(unique_rows)] += gather @ columns  # (unique rows, n)


def scatter_add_complex(xp, target, index, values) -> None:
    """target[index] += values for a contiguous 1-D complex128 ``target``, repeated indices summed (NumPy's
    add.at; CuPy's scatter_add on the real and imaginary parts, float64 atomics)."""
    if xp is np:
        np.add.at(target, index, values)
        return
    import cupyx  # noqa: PLC0415

    parts = target.view(np.float64)  # real, imag interleaved
    cupyx.scatter_add(parts, 2 * index, xp.ascontiguousarray(values.real))
    cupyx.scatter_add(parts, 2 * index + 1, xp.ascontiguousarray(values.imag))


def touching_pairs(dev: DeviceSurface, wavenumber: float, coupling: complex, budget_bytes: float = 0.5e9):
    """(rows, columns, values) of ``coupling * W - K`` over the touching element pairs (duplicates to be summed),
    bempp-cl's singular rule."""
    xp = dev.backend.xp
    s = dev.surface
    k = float(wavenumber)
    values = xp.zeros((len(s.touch_test), 3, 3), np.complex128)
    for g, count in enumerate(s.group_counts):
        count = int(count)
        members = np.flatnonzero(s.group_of_pair == g)
        chunk = int(max(1, budget_bytes // (16.0 * 12 * count)))
        test_ref = xp.asarray(s.group_test_points[g, :, :count])[None]  # (1, 2, c)
        trial_ref = xp.asarray(s.group_trial_points[g, :, :count])[None]
        weights = xp.asarray(s.group_weights[g, :count])[None]  # (1, c)
        test_shape = _p1_shape(xp, test_ref)[0]  # (c, 3)
        trial_shape = _p1_shape(xp, trial_ref)[0]
        for start in range(0, len(members), chunk):
            pairs = members[start:start + chunk]
            a = xp.asarray(s.touch_test[pairs])
            b = xp.asarray(s.touch_trial[pairs])
            x = _map_points(xp, dev.corners[a], test_ref)  # (P, c, 3)
            y = _map_points(xp, dev.corners[b], trial_ref)
            d = y - x
            r = xp.sqrt((d * d).sum(axis=2))
            kr = k * r
            green = xp.exp(1j * kr) * (INV_4PI / r) * weights
            green_sum = green.sum(axis=1)  # (P,)
            gradient = green * (1j * kr - 1.0) / (r * r) * (d * dev.normals[b][:, None, :]).sum(axis=2)
            normal_product = (dev.normals[a] * dev.normals[b]).sum(axis=1)
            value = (-coupling * k * k) * normal_product[:, None] * green - gradient  # (P, c)
            products = xp.einsum("pc,ci,cj->pij", value, test_shape, trial_shape)
            curl_product = xp.einsum("pic,pjc->pij", dev.curls[a], dev.curls[b])
            values[xp.asarray(pairs)] = (coupling * curl_product * green_sum[:, None, None] + products) \
                * (dev.integration_elements[a] * dev.integration_elements[b])[:, None, None]
    s_rows = np.broadcast_to(s.dofs[s.touch_test][:, :, None], (len(s.touch_test), 3, 3)).ravel()
    s_columns = np.broadcast_to(s.dofs[s.touch_trial][:, None, :], (len(s.touch_test), 3, 3)).ravel()
    signs = (s.multipliers[s.touch_test][:, :, None] * s.multipliers[s.touch_trial][:, None, :]).ravel()
    values = values.reshape(-1) * xp.asarray(signs)
    return s_rows, s_columns, values


def _map_points(xp, corners, reference):
    """Points of triangles (P, 3 corners, 3) at reference coordinates (P, 2, c) -> (P, c, 3)."""
    s = reference[:, 0, :, None]
    t = reference[:, 1, :, None]
    origin = corners[:, None, 0, :]
    return origin + s * (corners[:, None, 1, :] - origin) + t * (corners[:, None, 2, :] - origin)


def _p1_shape(xp, reference):
    """P1 shape functions (1 - s - t, s, t) at reference coordinates (P, 2, c) -> (P, c, 3)."""
    s = reference[:, 0, :]
    t = reference[:, 1, :]
    return xp.stack([1.0 - s - t, s, t], axis=2)


def add_sparse(dev: DeviceSurface, matrix, rows, columns, values) -> None:
    """matrix[rows, columns] += values with repeated (row, column) pairs summed."""
    xp = dev.backend.xp
    summed = dev.backend.sparse.coo_matrix((values, (xp.asarray(rows), xp.asarray(columns))), shape=matrix.shape)
    summed.sum_duplicates()
    matrix[summed.row, summed.col] += summed.data


def mass_terms(surface: SurfaceArrays) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The P1 Gram matrix as (rows, columns, values) to be summed (m^2): A/6 on the diagonal, A/12 off it."""
    area = surface.integration_elements / 2.0
    local = (np.full((3, 3), 1.0 / 12.0) + np.eye(3) / 12.0)[None] * area[:, None, None]
    rows = np.broadcast_to(surface.dofs[:, :, None], local.shape).ravel()
    columns = np.broadcast_to(surface.dofs[:, None, :], local.shape).ravel()
    signs = surface.multipliers[:, :, None] * surface.multipliers[:, None, :]
    return rows, columns, (local * signs).ravel()


def system_matrix(dev: DeviceSurface, wavenumber: float, coupling: complex, with_mass: bool = True,
                  budget_bytes: float = 0.5e9, fused: bool = False):
    """The dense Burton–Miller system ``coupling * W - K (+ M / 2)`` on the backend; with ``fused`` its far pairs by
    the one-pass CUDA kernel (:mod:`mesh2hrtf_io.bem_fused`: CuPy, or NumPy under numba's CUDA simulator)."""
    if fused:
        from .bem_fused import far_pairs_fused  # noqa: PLC0415

        matrix = far_pairs_fused(dev, wavenumber, coupling)
    else:
        matrix = far_pairs(dev, wavenumber, coupling, budget_bytes=budget_bytes)
    add_sparse(dev, matrix, *touching_pairs(dev, wavenumber, coupling, budget_bytes))
    if with_mass:
        rows, columns, values = mass_terms(dev.surface)
        add_sparse(dev, matrix, rows, columns, dev.backend.xp.asarray(0.5 * values))
    return matrix


def source_rhs(dev: DeviceSurface, ear_elements: np.ndarray, wavenumber: float, coupling: complex,
               normal_derivative: complex):
    """Right-hand side (n,) of a source whose ear elements carry the normal pressure derivative
    ``normal_derivative`` (Pa/m; i ω ρ v_n): ``-(V + coupling K') g`` tested with P1, minus ``coupling g / 2``
    times the P1 load of the ear elements. V single layer, K' adjoint double layer; far pairs with the Gauss rule,
    touching pairs with the singular rule."""
    xp = dev.backend.xp
    s = dev.surface
    k = float(wavenumber)
    ear = np.asarray(ear_elements, np.int64)
    ear_mask = np.zeros(dev.E, bool)
    ear_mask[ear] = True
    # far pairs: every test element against the ear elements, the touching ones masked out
    far = np.ones((dev.E, len(ear)))
    touching = ear_mask[s.touch_trial]
    position = np.full(dev.E, -1)
    position[ear] = np.arange(len(ear))
    far[s.touch_test[touching], position[s.touch_trial[touching]]] = 0.0
    far4 = xp.asarray(far)[:, None, :, None]
    x = dev.points  # (E, q, 3)
    y = dev.points[xp.asarray(ear)]  # (e, q, 3)
    d = y[None, None, :, :, :] - x[:, :, None, None, :]  # (E, q, e, q, 3)
    r = xp.sqrt((d * d).sum(axis=4)) * far4 + (1.0 - far4)
    kr = k * r
    green = xp.exp(1j * kr) * (INV_4PI / r) * dev.weights[:, :, None, None] * dev.weights[xp.asarray(ear)][None, None] * far4
    # dG/dn_x = -G (ikr - 1) / r^2 (y - x) . n_x
    adjoint = -green * (1j * kr - 1.0) / (r * r) * (d * dev.normals[:, None, None, None, :]).sum(axis=4)
    value = (green + coupling * adjoint).sum(axis=(2, 3))  # (E, q): summed over the ear's points
    local = value @ dev.shape  # (E, 3)
    # touching pairs with an ear element as trial
    local_touch = xp.zeros((dev.E, 3), np.complex128)
    for g, count in enumerate(s.group_counts):
        pairs = np.flatnonzero(touching & (s.group_of_pair == g))
        if not len(pairs):
            continue
        count = int(count)
        a = xp.asarray(s.touch_test[pairs])
        b = xp.asarray(s.touch_trial[pairs])
        test_ref = xp.asarray(s.group_test_points[g, :, :count])[None]
        trial_ref = xp.asarray(s.group_trial_points[g, :, :count])[None]
        xs = _map_points(xp, dev.corners[a], test_ref)
        ys = _map_points(xp, dev.corners[b], trial_ref)
        ds = ys - xs
        rs = xp.sqrt((ds * ds).sum(axis=2))
        krs = k * rs
        green_s = xp.exp(1j * krs) * (INV_4PI / rs) * xp.asarray(s.group_weights[g, :count])[None]
        adjoint_s = -green_s * (1j * krs - 1.0) / (rs * rs) * (ds * dev.normals[a][:, None, :]).sum(axis=2)
        block = (green_s + coupling * adjoint_s) @ _p1_shape(xp, test_ref)[0] \
            * (dev.integration_elements[a] * dev.integration_elements[b])[:, None]
        _add_rows(xp, local_touch, a, block)
    local = local + local_touch
    tested = xp.zeros(dev.n, np.complex128)  # (n,) with the P1 signs
    _add_rows(xp, tested, xp.asarray(s.dofs.ravel()), local.reshape(-1) * xp.asarray(s.multipliers.ravel()))
    load = xp.zeros(dev.n, np.float64)
    ear_dofs = xp.asarray(s.dofs[ear].ravel())
    ear_load = xp.asarray((s.multipliers[ear] * (s.integration_elements[ear] / 2.0)[:, None] / 3.0).ravel())
    _add_rows(xp, load, ear_dofs, ear_load)
    return -normal_derivative * tested - coupling * 0.5 * normal_derivative * load


def _add_rows(xp, target, index, values) -> None:
    """target[index] += values along the first axis, repeated indices summed."""
    if xp is np:
        np.add.at(target, index, values)
        return
    if target.ndim == 1 and not xp.iscomplexobj(target):
        import cupyx  # noqa: PLC0415

        cupyx.scatter_add(target, index, values)
        return
    width = int(np.prod(target.shape[1:]))
    linear = (index[:, None] * width + xp.arange(width)[None, :]).ravel()
    scatter_add_complex(xp, target.reshape(-1), linear, xp.asarray(values, dtype=np.complex128).reshape(-1))


def pressure_at_points(dev: DeviceSurface, points_m, coefficients, ears: list[np.ndarray], wavenumber: float,
                       normal_derivatives: list[complex], budget_bytes: float = 0.25e9):
    """Pressure (Pa) of each source (S of them) at points (m, shape (N, 3)) -> (S, N): double layer potential of the
    P1 surface pressure (``coefficients``, (n, S)) minus single layer potential of the source's normal derivative on
    its ear elements, bempp-cl's Gauss rule on every element. The kernel is evaluated once for all sources."""
    xp = dev.backend.xp
    k = float(wavenumber)
    points = xp.asarray(points_m, dtype=np.float64)
    E, q = dev.points.shape[:2]
    # surface pressure at the Gauss points: sum_j shape[q, j] sign[b, j] u[dof[b, j]]
    u_local = coefficients[dev.dofs] * dev.multipliers[:, :, None]  # (E, 3, S) signed dof values per corner
    u_points = xp.einsum("qj,ejs->eqs", dev.shape, u_local)  # (E, q, S)
    y = dev.points.reshape(E * q, 3)
    n_b = xp.repeat(dev.normals, q, axis=0)  # (E q, 3)
    double_weights = dev.weights.reshape(E * q, 1) * u_points.reshape(E * q, -1)  # (E q, S)
    ear_points = [dev.points[xp.asarray(np.asarray(ear, np.int64))].reshape(-1, 3) for ear in ears]
    ear_weights = [dev.weights[xp.asarray(np.asarray(ear, np.int64))].reshape(-1) for ear in ears]
    chunk = int(max(1, budget_bytes // (16.0 * 6 * E * q)))
    out = []
    for start in range(0, len(points), chunk):
        x = points[start:start + chunk]
        d0 = y[None, :, 0] - x[:, None, 0]  # (c, E q): y - x
        d1 = y[None, :, 1] - x[:, None, 1]
        d2 = y[None, :, 2] - x[:, None, 2]
        r = xp.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        normal = (d0 * n_b[None, :, 0] + d1 * n_b[None, :, 1] + d2 * n_b[None, :, 2]) / (r * r)
        kr = k * r
        double = xp.exp(1j * kr) * ((1j * kr - 1.0) * INV_4PI / r * normal)
        field = double @ double_weights  # (c, S)
        for index, (y_ear, w_ear) in enumerate(zip(ear_points, ear_weights)):
            r_ear = xp.sqrt(((y_ear[None, :, :] - x[:, None, :]) ** 2).sum(axis=2))
            single = (xp.exp(1j * k * r_ear) * (INV_4PI / r_ear)) @ w_ear
            field[:, index] -= normal_derivatives[index] * single
        out.append(field)
    return xp.concatenate(out).T


def solve_sources_arrays(dev: DeviceSurface, sources: list[tuple[np.ndarray, float]], points_m: np.ndarray,
                         frequency_hz: float, speed_of_sound_m_s: float, density_kg_m3: float,
                         system=None, timings: dict | None = None, budget_bytes: float = 0.5e9,
                         far_geometry=None, fused: bool = False) -> list[np.ndarray]:
    """Pressure (Pa, e^{-iωt}) at ``points_m`` for each source (ear element indices, normal velocity m/s): one
    system matrix and LU per frequency, every source a right-hand side. Returns host arrays. ``system``: a matrix
    assembled by another path (the CPU numba pass), used instead of assembling it here; ``timings``: filled with the
    seconds of each phase (assembly, lu, rhs, solve, potential); ``budget_bytes``: memory of the work arrays;
    ``far_geometry`` (:class:`burton_miller.FarFieldGeometry`, NumPy only): the potentials by its numba pass;
    ``fused``: the far pairs by the one-pass CUDA kernel (:mod:`mesh2hrtf_io.bem_fused`)."""
    import time  # noqa: PLC0415

    from .errors import Mesh2HrtfIoError  # noqa: PLC0415

    backend = dev.backend
    clock = [time.perf_counter()]

    def lap(name: str) -> None:
        if timings is not None:
            backend.synchronize()
            now = time.perf_counter()
            timings[name] = timings.get(name, 0.0) + now - clock[0]
            clock[0] = now

    k = 2.0 * np.pi * frequency_hz / speed_of_sound_m_s
    coupling = 1j / k
    matrix = (system_matrix(dev, k, coupling, budget_bytes=budget_bytes, fused=fused) if system is None
              else backend.asarray(system))
    lap("assembly")
    factors = backend.lu_factor(matrix)
    lap("lu")
    omega = 2.0 * np.pi * frequency_hz
    derivatives = [1j * omega * density_kg_m3 * velocity for _, velocity in sources]
    rhs = backend.xp.stack([source_rhs(dev, elements, k, coupling, g)
                            for (elements, _), g in zip(sources, derivatives)], axis=1)
    lap("rhs")
    coefficients = backend.lu_solve(factors, rhs)
    if not bool(backend.xp.isfinite(coefficients).all()):
        raise Mesh2HrtfIoError(f"the BEM system at {frequency_hz:g} Hz is singular (degenerate mesh?)")
    lap("solve")
    if far_geometry is not None and backend.name == "numpy":  # the CPU path: one numba pass (burton_miller.py)
        fields = _numba_potentials(dev, far_geometry, points_m, coefficients, sources, derivatives, k)
    else:
        fields = backend.to_host(pressure_at_points(dev, points_m, coefficients, [e for e, _ in sources], k,
                                                    derivatives, budget_bytes=budget_bytes / 2))
    pressures = [fields[index] for index in range(len(sources))]
    lap("potential")
    return pressures


def _numba_potentials(dev: DeviceSurface, far_geometry, points_m, coefficients, sources, derivatives,
                      wavenumber: float) -> np.ndarray:
    """(S, N) pressures by :func:`burton_miller.potentials`: the weights of each source at the Gauss points."""
    from . import burton_miller  # noqa: PLC0415

    E, q = dev.points.shape[:2]
    u_local = coefficients[dev.surface.dofs] * dev.surface.multipliers[:, :, None]  # (E, 3, S)
    surface_weights = np.einsum("qj,ejs->eqs", dev.surface.shape, u_local) * dev.surface.weights[:, :, None]
    ear_weights = np.zeros((E, q, len(sources)), np.complex128)
    for index, ((elements, _), g) in enumerate(zip(sources, derivatives)):
        ear_weights[np.asarray(elements, np.int64), :, index] = g * dev.surface.weights[np.asarray(elements, np.int64)]
    return burton_miller.potentials(far_geometry, points_m, surface_weights, ear_weights, wavenumber).T
