"""The probe of one embedded-solver backend, run in a child process by :func:`mesh2hrtf_io.backends.probe`:
``python -m mesh2hrtf_io.backend_probe opencl|cuda --out FILE``.

It builds a kernel with the vector math the backend's kernels use, then solves one frequency of a small sphere with
the backend and with numba and compares them; the verdict (ok, reason, details) goes to FILE as JSON. Whatever
native library aborts here takes down only this process.
"""
from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from .backends import PROBE_TOLERANCE, no_core_dumps


def _probe_sphere(backend: str) -> dict:
    """One frequency of a 162-vertex sphere with both ears, solved by ``backend`` and by numba: largest relative
    difference of the pressures on 50 directions."""
    import numpy as np  # noqa: PLC0415
    import trimesh  # noqa: PLC0415

    from . import bem  # noqa: PLC0415

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.0875)
    ears = [[int(np.argmin(np.linalg.norm(sphere.triangles_center - [0, side * 0.0875, 0], axis=1)))]
            for side in (1, -1)]
    directions = np.random.default_rng(0).normal(size=(50, 3))
    points = 1.2 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    results = {}
    for name in (backend, "numba"):
        bem.set_backend(name)
        results[name] = np.array(bem.solve_sources(sphere.vertices, sphere.faces, [(ears[0], 0.1), (ears[1], 0.1)],
                                                   points, 3000.0, 343.0, 1.2))
    return {"max_relative_difference": float(np.max(np.abs(results[backend] - results["numba"])
                                                     / np.abs(results["numba"])))}


def _probe_opencl_kernel() -> dict:
    """Build and run, on pyopencl's CPU device, a kernel with the vector math of bempp-cl's Helmholtz kernels
    (sqrt, rsqrt, sin, cos, exp on vectors of doubles of the device's native width, as bempp-cl builds them)."""
    import numpy as np  # noqa: PLC0415
    import pyopencl as cl  # noqa: PLC0415

    devices = [d for p in cl.get_platforms() for d in p.get_devices() if d.type & cl.device_type.CPU]
    if not devices:
        raise RuntimeError("pyopencl lists no CPU device")
    device = devices[0]
    width = max(1, int(device.native_vector_width_double))
    vector = "double" if width == 1 else f"double{width}"
    source = f"""
    __kernel void probe(__global const {vector} *a, __global {vector} *b) {{
        size_t i = get_global_id(0);
        {vector} x = a[i];
        {vector} r = sqrt(x);
        b[i] = r * rsqrt(x + 1.0) + sin(x) * cos(x) + exp(-x);
    }}"""
    context = cl.Context([device])
    queue = cl.CommandQueue(context)
    values = np.linspace(0.1, 4.0, 64 * width)
    flags = cl.mem_flags
    a = cl.Buffer(context, flags.READ_ONLY | flags.COPY_HOST_PTR, hostbuf=values)
    b = cl.Buffer(context, flags.WRITE_ONLY, values.nbytes)
    program = cl.Program(context, source).build()
    program.probe(queue, (64,), None, a, b)
    out = np.empty_like(values)
    cl.enqueue_copy(queue, out, b)
    queue.finish()
    expected = np.sqrt(values) / np.sqrt(values + 1.0) + np.sin(values) * np.cos(values) + np.exp(-values)
    return {"device": device.name.strip(), "vector": vector,
            "kernel_max_error": float(np.max(np.abs(out - expected)))}


def _probe_cuda_kernel() -> dict:
    """CuPy on the GPU: complex exponentials of a vector, against NumPy."""
    import cupy  # noqa: PLC0415
    import numpy as np  # noqa: PLC0415

    count = cupy.cuda.runtime.getDeviceCount()
    if count < 1:
        raise RuntimeError("CuPy sees no CUDA device")
    properties = cupy.cuda.runtime.getDeviceProperties(0)
    values = np.linspace(0.1, 40.0, 4096)
    out = cupy.asnumpy(cupy.exp(1j * cupy.asarray(values)) / cupy.asarray(values))
    free, total = cupy.cuda.Device(0).mem_info
    return {"device": properties["name"].decode() if isinstance(properties["name"], bytes) else str(properties["name"]),
            "memory_total_gb": round(total / 1e9, 1), "memory_free_gb": round(free / 1e9, 1),
            "kernel_max_error": float(np.max(np.abs(out - np.exp(1j * values) / values)))}


def _child(backend: str, out: Path) -> None:
    details = _probe_opencl_kernel() if backend == "opencl" else _probe_cuda_kernel()
    if details["kernel_max_error"] > 1e-12:
        verdict = {"ok": False, "reason": f"its kernel computes wrong values (error {details['kernel_max_error']:.1e})"}
    else:
        details.update(_probe_sphere(backend))
        difference = details["max_relative_difference"]
        verdict = ({"ok": True, "reason": f"{details['device']}: kernel and sphere solve agree with numba "
                                          f"({difference:.1e})"} if difference < PROBE_TOLERANCE else
                   {"ok": False, "reason": f"its sphere solve differs from numba's by {difference:.1e} (relative)"})
    out.write_text(json.dumps({**verdict, "details": details}))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("backend", choices=["opencl", "cuda"])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    no_core_dumps()  # a backend that aborts here must not dump a driver's address space
    _child(args.backend, args.out)


if __name__ == "__main__":
    main()
