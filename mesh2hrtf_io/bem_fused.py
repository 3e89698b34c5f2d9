"""The far element pairs of the Burton–Miller system ``coupling * W - K`` in one fused CUDA kernel (numba.cuda).

:func:`mesh2hrtf_io.bem_arrays.far_pairs` evaluates the far pairs as whole-array operations: about 25 passes over
(chunk, q, E, q) work arrays per chunk, 93 % of a frequency's time on the GPU. Here each thread takes one element
pair (test a, trial b) that shares no vertex, evaluates its q x q Gauss points once, keeps the 3 x 3 local block in
registers and adds it straight into the dense matrix (float64 atomics on the real and imaginary parts):

    block[i, j] = sum_pq shape[p, i] (-c k^2 (n_a . n_b) G_pq - G_pq (ik r - 1) / r^2 ((y_q - x_p) . n_b)) shape[q, j]
                  + c (curl_a,i . curl_b,j) sum_pq G_pq,      G_pq = w_a,p w_b,q e^{ikr} / (4 pi r),

    matrix[dof[a, i], dof[b, j]] += sign[a, i] sign[b, j] block[i, j],

the very arithmetic of the array code (SI units, e^{-iωt}, normals out of the head). Touching pairs (a shared P1
degree of freedom, i.e. a shared vertex) are left to the singular rule, as there. On a machine without a GPU the same
kernel runs in numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``), which the tests use to check it against the
array code; the simulator is for checking only (seconds for a hundred elements).
"""
from __future__ import annotations

import math

import numpy as np
from numba import cuda  # compiles nothing at import; the simulator replaces it where NUMBA_ENABLE_CUDASIM=1

#: Threads per block edge (a 2-D block of test x trial elements).
BLOCK = 16
INV_4PI = 1.0 / (4.0 * math.pi)


@cuda.jit
def far_pair_kernel(points, weights, normals, curls, shape, dofs, signs, k, c_re, c_im, out):
    a, b = cuda.grid(2)
    n_elements = points.shape[0]
    if a >= n_elements or b >= n_elements:
        return
    for i in range(3):  # a shared vertex: the singular rule's pair
        for j in range(3):
            if dofs[a, i] == dofs[b, j]:
                return
    q = points.shape[1]
    nb0, nb1, nb2 = normals[b, 0], normals[b, 1], normals[b, 2]
    nn = normals[a, 0] * nb0 + normals[a, 1] * nb1 + normals[a, 2] * nb2
    # -c k^2 (n_a . n_b): the hypersingular part's normal-product factor
    f_re, f_im = -c_re * k * k * nn, -c_im * k * k * nn
    acc_re = cuda.local.array(9, np.float64)
    acc_im = cuda.local.array(9, np.float64)
    for m in range(9):
        acc_re[m] = 0.0
        acc_im[m] = 0.0
    sum_re, sum_im = 0.0, 0.0
    for p in range(q):
        x0, x1, x2 = points[a, p, 0], points[a, p, 1], points[a, p, 2]
        wa = weights[a, p]
        # the trial side's kernel contracted with its shape functions: t[j] = sum_q kernel_pq shape[q, j]
        t0_re, t0_im, t1_re, t1_im, t2_re, t2_im = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for s in range(q):
            d0 = points[b, s, 0] - x0
            d1 = points[b, s, 1] - x1
            d2 = points[b, s, 2] - x2
            r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            kr = k * r
            scale = wa * weights[b, s] * INV_4PI / r
            g_re, g_im = scale * math.cos(kr), scale * math.sin(kr)
            sum_re += g_re
            sum_im += g_im
            # gradient factor G (ikr - 1) / r^2 times (y - x) . n_b
            dn = (d0 * nb0 + d1 * nb1 + d2 * nb2) / (r * r)
            h_re = (-g_re - g_im * kr) * dn
            h_im = (g_re * kr - g_im) * dn
            v_re = f_re * g_re - f_im * g_im - h_re
            v_im = f_re * g_im + f_im * g_re - h_im
            s0, s1, s2 = shape[s, 0], shape[s, 1], shape[s, 2]
            t0_re += v_re * s0
            t0_im += v_im * s0
            t1_re += v_re * s1
            t1_im += v_im * s1
            t2_re += v_re * s2
            t2_im += v_im * s2
        for i in range(3):
            si = shape[p, i]
            acc_re[3 * i] += si * t0_re
            acc_im[3 * i] += si * t0_im
            acc_re[3 * i + 1] += si * t1_re
            acc_im[3 * i + 1] += si * t1_im
            acc_re[3 * i + 2] += si * t2_re
            acc_im[3 * i + 2] += si * t2_im
    # c (curl_a,i . curl_b,j) sum G, then into the matrix with the degrees of freedom's signs
    cg_re, cg_im = c_re * sum_re - c_im * sum_im, c_re * sum_im + c_im * sum_re
    for i in range(3):
        row = dofs[a, i]
        for j in range(3):
            curl = (curls[a, i, 0] * curls[b, j, 0] + curls[a, i, 1] * curls[b, j, 1]
                    + curls[a, i, 2] * curls[b, j, 2])
            sign = signs[a, i] * signs[b, j]
            column = dofs[b, j]
            cuda.atomic.add(out, (row, 2 * column), sign * (acc_re[3 * i + j] + curl * cg_re))
            cuda.atomic.add(out, (row, 2 * column + 1), sign * (acc_im[3 * i + j] + curl * cg_im))



def far_pairs_fused(dev, wavenumber: float, coupling: complex):
    """Dense (n, n) ``coupling * W - K`` over the far element pairs of ``dev`` (a
    :class:`mesh2hrtf_io.bem_arrays.DeviceSurface` on CuPy, or on NumPy under the CUDA simulator) by the fused
    kernel; the same as :func:`mesh2hrtf_io.bem_arrays.far_pairs`."""
    xp = dev.backend.xp
    kernel = far_pair_kernel
    n_elements = int(dev.E)
    out = xp.zeros((dev.n, 2 * dev.n), np.float64)  # real and imaginary parts interleaved, as complex128 is
    dofs = xp.asarray(dev.surface.dofs, dtype=np.int64)
    signs = xp.asarray(dev.surface.multipliers, dtype=np.float64)
    grid = ((n_elements + BLOCK - 1) // BLOCK, (n_elements + BLOCK - 1) // BLOCK)
    c = complex(coupling)
    kernel[grid, (BLOCK, BLOCK)](xp.ascontiguousarray(dev.points), xp.ascontiguousarray(dev.weights),
                                 xp.ascontiguousarray(dev.normals), xp.ascontiguousarray(dev.curls),
                                 xp.ascontiguousarray(dev.shape), dofs, signs, float(wavenumber), c.real, c.imag, out)
    return out.view(np.complex128)
