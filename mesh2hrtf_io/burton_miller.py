"""The far (regular) part of the Burton–Miller system matrix, assembled in one pass for both operators.

The embedded solver's system is ``i/k * W - K + M/2`` on continuous piecewise-linear (P1) functions: W the
Helmholtz hypersingular operator, K the double layer, both in bempp-cl's Galerkin form with the same kernel
G = e^{ikr} / (4 pi r) (SI units, metres, e^{-iwt}). bempp-cl assembles W and K one after the other, each over
every ordered element pair. Here every *unordered* pair of elements that share no vertex is visited once: the
point-pair distances and e^{ikr} are computed once and give the four 3 x 3 blocks (W and K, test a / trial b and
test b / trial a), because W's kernel is symmetric and K's differs between the two orders only by which normal
enters. That is a quarter of bempp-cl's kernel evaluations.

Element pairs that share a vertex, an edge or the element itself are left out: bempp-cl's singular
(Sauter–Schwab) quadrature gives their full values (``bem.solve_sources``), exactly as in its own dense assembly.
The quadrature of the far pairs is bempp-cl's triangle Gauss rule of the same order, so the sum equals bempp-cl's
operators to rounding (tests/test_mesh2hrtf_io_bem.py).
"""
from __future__ import annotations

import dataclasses

import numba
import numpy as np

INV_4PI = 1.0 / (4.0 * np.pi)


@dataclasses.dataclass(frozen=True)
class FarFieldGeometry:
    """What the far-pair assembly needs of a P1 surface, independent of frequency (metres).

    points: (elements, q, 3) quadrature points; weights: (elements, q) Gauss weights times the element's
    integration element (twice its area, m^2); shape: (q, 3) P1 shape values at the points; normals: (elements, 3)
    outward unit normals; curls: (elements, 3 shape functions, 3) surface curls n x grad(phi) (1/m); triangles:
    (elements, 3) vertex indices; dofs and multipliers: (elements, 3) P1 degrees of freedom and their signs;
    colour_order, colour_offsets: elements sorted by colour (no two elements of a colour share a degree of
    freedom) and where each colour starts."""

    points: np.ndarray
    weights: np.ndarray
    shape: np.ndarray
    normals: np.ndarray
    curls: np.ndarray
    triangles: np.ndarray
    dofs: np.ndarray
    multipliers: np.ndarray
    colour_order: np.ndarray
    colour_offsets: np.ndarray
    dof_count: int


def far_field_geometry(grid, p1, quadrature_order: int) -> FarFieldGeometry:
    """Frequency-independent geometry of a bempp-cl grid and its P1 space, with bempp-cl's triangle Gauss rule of
    `quadrature_order` (its ``quadrature.regular`` parameter)."""
    from bempp_cl.api.integration.triangle_gauss import rule  # noqa: PLC0415

    local_points, gauss_weights = rule(quadrature_order)  # (2, q) reference coordinates, (q,) weights
    s, t = local_points
    shape = np.stack([1.0 - s - t, s, t], axis=1)  # bempp-cl's P1 shape functions on the reference triangle
    corners = grid.vertices.T[grid.elements.T]  # (elements, 3 corners, 3)
    points = corners[:, None, 0] + s[None, :, None] * (corners[:, None, 1] - corners[:, None, 0]) \
        + t[None, :, None] * (corners[:, None, 2] - corners[:, None, 0])
    normals = grid.normals * p1.normal_multipliers[:, None]
    reference_gradient = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
    gradients = np.einsum("eij,jf->efi", grid.jacobian_inverse_transposed, reference_gradient)  # (elements, shape fn, 3)
    curls = np.cross(normals[:, None, :], gradients)
    colours = np.asarray(p1.color_map)
    order = np.argsort(colours, kind="stable").astype(np.int64)
    offsets = np.searchsorted(colours[order], np.arange(colours.max() + 2)).astype(np.int64)
    return FarFieldGeometry(
        points=np.ascontiguousarray(points, np.float64),
        weights=np.ascontiguousarray(gauss_weights[None, :] * grid.integration_elements[:, None], np.float64),
        shape=np.ascontiguousarray(shape, np.float64), normals=np.ascontiguousarray(normals, np.float64),
        curls=np.ascontiguousarray(curls, np.float64),
        triangles=np.ascontiguousarray(grid.elements.T, np.int64),
        dofs=np.ascontiguousarray(p1.local2global, np.int64),
        multipliers=np.ascontiguousarray(p1.local_multipliers, np.float64),
        colour_order=order, colour_offsets=offsets, dof_count=int(p1.global_dof_count))


def assemble_far_pairs(geometry: FarFieldGeometry, wavenumber: float, coupling: complex) -> np.ndarray:
    """Dense (dofs, dofs) complex matrix: ``coupling * W - K`` summed over the element pairs that share no vertex
    (the adjacent pairs are zero here). `wavenumber` in 1/m."""
    n = geometry.dof_count
    matrix = np.zeros((n, n), np.complex128)
    transposed = np.zeros((n, n), np.complex128)
    g = geometry
    _far_pairs(g.points, g.weights, g.shape, g.normals, g.curls, g.triangles, g.dofs, g.multipliers,
               g.colour_order, g.colour_offsets, float(wavenumber), complex(coupling), matrix, transposed)
    np.add(matrix, transposed.T, out=matrix)
    return matrix


@numba.njit(parallel=True, cache=True, fastmath=True, boundscheck=False)
def _far_pairs(points, weights, shape, normals, curls, triangles, dofs, multipliers, colour_order, colour_offsets,
               wavenumber, coupling, matrix, transposed):  # pragma: no cover - compiled by numba
    """Visit each unordered pair {a, b} of elements sharing no vertex once: b = a + 1 ... a + n/2 (mod n), so that
    every element does the same work. The block of test a / trial b goes to ``matrix``, the block of test b /
    trial a to ``transposed`` (transposed, so that both are written in the rows of a's degrees of freedom: the
    elements of one colour share none, so the threads of a colour never write the same row)."""
    n_elements = points.shape[0]
    n_points = points.shape[1]
    half = n_elements // 2
    k2 = wavenumber * wavenumber
    for colour in range(colour_offsets.shape[0] - 1):
        members = colour_order[colour_offsets[colour]:colour_offsets[colour + 1]]
        for index in numba.prange(members.shape[0]):
            a = members[index]
            pair_ab = np.empty((n_points, n_points), np.complex128)
            pair_ba = np.empty((n_points, n_points), np.complex128)
            half_ab = np.empty((n_points, 3), np.complex128)
            half_ba = np.empty((n_points, 3), np.complex128)
            for offset in range(1, half + 1):
                b = a + offset
                if b >= n_elements:
                    b -= n_elements
                if 2 * offset == n_elements and a >= half:
                    continue  # the pair {a, a + n/2} is visited from its lower element only
                adjacent = False
                for i in range(3):
                    for j in range(3):
                        if triangles[a, i] == triangles[b, j]:
                            adjacent = True
                if adjacent:
                    continue
                normal_product = (normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1]
                                  + normals[a, 2] * normals[b, 2])
                green_sum = 0.0 + 0.0j
                for p in range(n_points):
                    for q in range(n_points):
                        d0 = points[b, q, 0] - points[a, p, 0]
                        d1 = points[b, q, 1] - points[a, p, 1]
                        d2 = points[b, q, 2] - points[a, p, 2]
                        r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                        kr = wavenumber * r
                        green = (np.cos(kr) + 1j * np.sin(kr)) * (INV_4PI / r) * weights[a, p] * weights[b, q]
                        green_sum += green
                        # W's k^2 (n_a . n_b) G term, minus dG/dn_y: y on b (test a, trial b) or on a (test b, trial a)
                        normal_term = -coupling * k2 * normal_product * green
                        gradient = green * (1j * kr - 1.0) / (r * r)
                        pair_ab[p, q] = normal_term - gradient * (d0 * normals[b, 0] + d1 * normals[b, 1]
                                                                  + d2 * normals[b, 2])
                        pair_ba[p, q] = normal_term + gradient * (d0 * normals[a, 0] + d1 * normals[a, 1]
                                                                  + d2 * normals[a, 2])
                for p in range(n_points):  # contract with the trial shape functions, then the test ones
                    for j in range(3):
                        sum_ab = 0.0 + 0.0j
                        sum_ba = 0.0 + 0.0j
                        for q in range(n_points):
                            sum_ab += pair_ab[p, q] * shape[q, j]
                            sum_ba += pair_ba[p, q] * shape[q, j]
                        half_ab[p, j] = sum_ab
                        half_ba[p, j] = sum_ba
                for i in range(3):
                    row = dofs[a, i]
                    for j in range(3):
                        curl_product = (curls[a, i, 0] * curls[b, j, 0] + curls[a, i, 1] * curls[b, j, 1]
                                        + curls[a, i, 2] * curls[b, j, 2])
                        value_ab = coupling * curl_product * green_sum
                        value_ba = value_ab
                        for p in range(n_points):
                            value_ab += shape[p, i] * half_ab[p, j]
                            value_ba += shape[p, i] * half_ba[p, j]
                        sign = multipliers[a, i] * multipliers[b, j]
                        matrix[row, dofs[b, j]] += sign * value_ab
                        transposed[row, dofs[b, j]] += sign * value_ba
