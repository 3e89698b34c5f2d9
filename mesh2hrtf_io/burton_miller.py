"""The Burton–Miller system matrix ``i/k W - K`` assembled in one pass for both operators.

The embedded solver's system is ``i/k * W - K + M/2`` on continuous piecewise-linear (P1) functions: W the
Helmholtz hypersingular operator, K the double layer, both in bempp-cl's Galerkin form with the same kernel
G = e^{ikr} / (4 pi r) (SI units, metres, e^{-iwt}). bempp-cl assembles W and K one after the other, each over
every ordered element pair. Here G and its gradient are evaluated once per quadrature point for both operators:

- far pairs (sharing no vertex), bempp-cl's triangle Gauss rule: every *unordered* pair is visited once, its
  point distances and e^{ikr} giving the four 3 x 3 blocks (W and K, test a / trial b and test b / trial a),
  because W's kernel is symmetric and K's differs between the two orders only by which normal enters: a quarter of
  bempp-cl's kernel evaluations;
- touching pairs (a shared vertex, edge or the element itself), bempp-cl's singular (Sauter–Schwab) rule and
  points, both operators from one evaluation (half of bempp-cl's).

The sum equals bempp-cl's own dense assembly to rounding (tests/test_mesh2hrtf_io_bem.py).
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
    integration element (twice its area, m^2); corners: (elements, 3, 3) vertex positions; integration_elements:
    (elements,); shape: (q, 3) P1 shape values at the points; normals: (elements, 3)
    outward unit normals; curls: (elements, 3 shape functions, 3) surface curls n x grad(phi) (1/m); triangles:
    (elements, 3) vertex indices; dofs and multipliers: (elements, 3) P1 degrees of freedom and their signs;
    colour_order, colour_offsets: elements sorted by colour (no two elements of a colour share a degree of
    freedom) and where each colour starts."""

    points: np.ndarray
    weights: np.ndarray
    corners: np.ndarray
    integration_elements: np.ndarray
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
        corners=np.ascontiguousarray(corners, np.float64),
        integration_elements=np.ascontiguousarray(grid.integration_elements, np.float64),
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


@dataclasses.dataclass(frozen=True)
class SingularPairs:
    """bempp-cl's singular quadrature of the element pairs that share a vertex, an edge or the element itself,
    independent of frequency: per pair its test and trial element, where its points and weights start and how many
    there are (reference coordinates, Sauter-Schwab rules of bempp-cl's ``quadrature.singular`` order), and the
    P1 degrees of freedom and signs its 3 x 3 block goes to (flattened, pair-major)."""

    test_points: np.ndarray
    trial_points: np.ndarray
    weights: np.ndarray
    test_elements: np.ndarray
    trial_elements: np.ndarray
    test_offsets: np.ndarray
    trial_offsets: np.ndarray
    weight_offsets: np.ndarray
    counts: np.ndarray
    rows: np.ndarray
    columns: np.ndarray
    signs: np.ndarray


def singular_pairs(grid, p1, order: int) -> SingularPairs:
    """The touching element pairs of a P1 space with bempp-cl's singular quadrature rule of `order`."""
    from bempp_cl.core.singular_assembler import _SingularQuadratureRuleInterfaceGalerkin  # noqa: PLC0415

    support = p1.localised_space.support
    rule = _SingularQuadratureRuleInterfaceGalerkin(grid, order, support, support)
    (test_points, trial_points, weights, test_elements, trial_elements, test_offsets, trial_offsets,
     weight_offsets, counts) = rule.get_arrays()
    test = np.asarray(test_elements, np.int64)
    trial = np.asarray(trial_elements, np.int64)
    local = np.arange(3)
    shape = (len(test), 3, 3)
    rows = np.broadcast_to(p1.local2global[test][:, :, None], shape)
    columns = np.broadcast_to(p1.local2global[trial][:, None, :], shape)
    signs = (p1.local_multipliers[test[:, None, None], local[None, :, None]]
             * p1.local_multipliers[trial[:, None, None], local[None, None, :]])
    return SingularPairs(
        test_points=np.ascontiguousarray(test_points, np.float64),
        trial_points=np.ascontiguousarray(trial_points, np.float64),
        weights=np.ascontiguousarray(weights, np.float64), test_elements=test, trial_elements=trial,
        test_offsets=np.asarray(test_offsets, np.int64), trial_offsets=np.asarray(trial_offsets, np.int64),
        weight_offsets=np.asarray(weight_offsets, np.int64), counts=np.asarray(counts, np.int64),
        rows=rows.ravel().astype(np.int64), columns=columns.ravel().astype(np.int64),
        signs=signs.ravel().astype(np.float64))


def add_singular_pairs(system: np.ndarray, pairs: SingularPairs, geometry: FarFieldGeometry,
                       wavenumber: float, coupling: complex) -> None:
    """Add ``coupling * W - K`` over the touching element pairs to the dense P1 `system`: both operators from one
    evaluation of e^{ikr} per quadrature point (bempp-cl evaluates them one operator at a time)."""
    blocks = np.zeros((len(pairs.test_elements), 3, 3), np.complex128)
    _singular_pairs(geometry.corners, geometry.integration_elements, geometry.normals,
                    geometry.curls, pairs.test_points, pairs.trial_points, pairs.weights, pairs.test_elements,
                    pairs.trial_elements, pairs.test_offsets, pairs.trial_offsets, pairs.weight_offsets,
                    pairs.counts, float(wavenumber), complex(coupling), blocks)
    np.add.at(system, (pairs.rows, pairs.columns), blocks.ravel() * pairs.signs)


@numba.njit(parallel=True, cache=True, fastmath=True, boundscheck=False)
def _singular_pairs(corners, integration_elements, normals, curls, test_points, trial_points, weights,
                    test_elements, trial_elements, test_offsets, trial_offsets, weight_offsets, counts,
                    wavenumber, coupling, blocks):  # pragma: no cover - compiled by numba
    """Per touching pair (test a, trial b): sum over its quadrature points of G = e^{ikr}/(4 pi r) times
    coupling * (curl_a . curl_b - k^2 n_a . n_b phi_i phi_j) - dG/dn_b phi_i phi_j, P1 shape functions
    phi = (1 - s - t, s, t) at the points' reference coordinates; times both integration elements."""
    k2 = wavenumber * wavenumber
    for pair in numba.prange(test_elements.shape[0]):
        a = test_elements[pair]
        b = trial_elements[pair]
        normal_product = normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1] + normals[a, 2] * normals[b, 2]
        green_sum = 0.0 + 0.0j
        products = np.zeros((3, 3), np.complex128)
        test_shape = np.empty(3)
        trial_shape = np.empty(3)
        for q in range(counts[pair]):
            s_test = test_points[0, test_offsets[pair] + q]
            t_test = test_points[1, test_offsets[pair] + q]
            s_trial = trial_points[0, trial_offsets[pair] + q]
            t_trial = trial_points[1, trial_offsets[pair] + q]
            d = np.empty(3)
            for c in range(3):
                x = corners[a, 0, c] + s_test * (corners[a, 1, c] - corners[a, 0, c]) \
                    + t_test * (corners[a, 2, c] - corners[a, 0, c])
                y = corners[b, 0, c] + s_trial * (corners[b, 1, c] - corners[b, 0, c]) \
                    + t_trial * (corners[b, 2, c] - corners[b, 0, c])
                d[c] = y - x
            r = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            kr = wavenumber * r
            green = (np.cos(kr) + 1j * np.sin(kr)) * (INV_4PI / r) * weights[weight_offsets[pair] + q]
            green_sum += green
            gradient = green * (1j * kr - 1.0) / (r * r) * (d[0] * normals[b, 0] + d[1] * normals[b, 1]
                                                            + d[2] * normals[b, 2])
            value = -coupling * k2 * normal_product * green - gradient
            test_shape[0] = 1.0 - s_test - t_test
            test_shape[1] = s_test
            test_shape[2] = t_test
            trial_shape[0] = 1.0 - s_trial - t_trial
            trial_shape[1] = s_trial
            trial_shape[2] = t_trial
            for i in range(3):
                for j in range(3):
                    products[i, j] += value * test_shape[i] * trial_shape[j]
        scale = integration_elements[a] * integration_elements[b]
        for i in range(3):
            for j in range(3):
                curl_product = curls[a, i, 0] * curls[b, j, 0] + curls[a, i, 1] * curls[b, j, 1] \
                    + curls[a, i, 2] * curls[b, j, 2]
                blocks[pair, i, j] = (coupling * curl_product * green_sum + products[i, j]) * scale


def potentials(geometry: FarFieldGeometry, points_m: np.ndarray, surface_weights: np.ndarray,
               ear_weights: np.ndarray, wavenumber: float) -> np.ndarray:
    """(points, sources) complex: sum over the surface's Gauss points y of dG/dn_y(x, y) times ``surface_weights``
    (elements, q, sources) minus sum of G(x, y) times ``ear_weights`` (elements, q, sources), at every point x
    (metres): the double layer potential of each source's surface pressure and the single layer potential of its
    ear's normal derivative, the weights carrying the Gauss weights (the CPU twin of bem_arrays.pressure_at_points,
    one numba pass per point, parallel over points)."""
    out = np.zeros((len(points_m), surface_weights.shape[2]), np.complex128)
    _potentials(geometry.points, geometry.normals, np.ascontiguousarray(points_m, np.float64),
                np.ascontiguousarray(surface_weights, np.complex128), np.ascontiguousarray(ear_weights, np.complex128),
                float(wavenumber), out)
    return out


@numba.njit(parallel=True, cache=True, fastmath=True, boundscheck=False)
def _potentials(points, normals, targets, surface_weights, ear_weights, wavenumber, out):  # pragma: no cover
    n_elements, n_points = points.shape[0], points.shape[1]
    n_sources = surface_weights.shape[2]
    for t in numba.prange(targets.shape[0]):
        x0, x1, x2 = targets[t, 0], targets[t, 1], targets[t, 2]
        for e in range(n_elements):
            any_ear = False
            for s in range(n_sources):
                for p in range(n_points):
                    if ear_weights[e, p, s] != 0:
                        any_ear = True
            for p in range(n_points):
                d0 = points[e, p, 0] - x0
                d1 = points[e, p, 1] - x1
                d2 = points[e, p, 2] - x2
                r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                kr = wavenumber * r
                green = (np.cos(kr) + 1j * np.sin(kr)) * (INV_4PI / r)
                double = green * (1j * kr - 1.0) / (r * r) * (d0 * normals[e, 0] + d1 * normals[e, 1]
                                                              + d2 * normals[e, 2])
                for s in range(n_sources):
                    out[t, s] += double * surface_weights[e, p, s]
                    if any_ear:
                        out[t, s] -= green * ear_weights[e, p, s]
