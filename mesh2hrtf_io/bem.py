"""Embedded BEM solver for machines without NumCalc: bempp-cl, Burton–Miller formulation.

Same physics as a reciprocal Mesh2HRTF project: the exterior Helmholtz problem around a rigid head
whose ear-canal element(s) vibrate with a normal velocity of 0.1 m/s. The Burton–Miller combination
of the conventional and hypersingular boundary integral equations has a unique solution at every
frequency, including the interior resonances of the head where the conventional equation fails.
Conventions follow NumCalc: time factor e^{-iωt} (outgoing waves e^{ikr}), SI units, normals out
of the head. Pressure is piecewise linear (P1) on the surface, the prescribed normal velocity
piecewise constant (DP0). Dense operators: memory grows with the square of the vertex count, so
this solver suits coarse meshes (up to about 10 000 vertices) and moderate frequencies; see
:func:`estimate_cost`.
"""
from __future__ import annotations

import dataclasses
import logging
import os
import time

import numpy as np

from .constants import EAR_VELOCITY_M_S
from .errors import Mesh2HrtfIoError

log = logging.getLogger(__name__)
# dense operator assembly on 2 cores, per entry of the two P1 operators: Mesh2HRTF's example head (8718 vertices, 152
# million entries, left ear) took 125 s for its first frequency with the one-pass far pairs (burton_miller.py) and
# bempp-cl's OpenCL singular pairs, LU included (benchmarks/solve_cost.py; the model says 130 s). bempp-cl's numba
# assembly of both operators took 880-990 s (5.8e-6 s per entry) and 4.3 GB of resident memory.
SECONDS_PER_ENTRY = 4.0e-7
MEMORY_OVERHEAD = 1.75  # resident memory / (16 bytes x dense entries): buffers, LU workspace
LU_SECONDS_PER_CUBE = 1e-10  # dense complex LU factorisation (LAPACK), per vertex count cubed
EAR_SEGMENT = 1  # domain index of the vibrating (ear) elements
#: Gauss points per triangle of bempp's regular (non-adjacent) element pairs: order 2 = 3 points, 9 point pairs
#: per element pair instead of order 4's 36. On the 642-vertex sphere against the series the largest error is
#: the same (0.015 / 0.051 / 0.72 dB at 0.5 / 2 / 8 kHz with either order; tests/test_mesh2hrtf_io_bem.py);
#: the singular (adjacent) pairs keep bempp's default order.
REGULAR_QUADRATURE_ORDER = 2
#: Order of bempp's singular (Sauter-Schwab) quadrature for element pairs that share a vertex, an edge or the element
#: itself: bempp's default, pinned here. Order 6 gives the sphere the same error against the series (2-20 kHz,
#: studies/singular_quadrature.py) at 2.7 times the cost; on a demo head the two differ by < 0.1 dB at 10 kHz.
SINGULAR_QUADRATURE_ORDER = 4


#: Backends of the embedded solver (mesh2hrtf_io/backends.py says what each computes where, and how they are probed).
DEVICES = ("numba", "opencl", "cuda")
#: bempp-cl modules whose numba functions take only arrays and can be cached on disk (numba's assembly kernels
#: take other jitted functions as arguments and cannot)
GRID_AND_SPACE_MODULES = ("bempp_cl.api.grid.grid", "bempp_cl.api.space.scalar_spaces", "bempp_cl.api.space.space",
                          "bempp_cl.api.space.shapesets")
_device_state: dict[str, object] = {"device": None}


def opencl_cpu_available() -> bool:
    """True when pyopencl imports and offers a CPU device (pocl's, or a vendor driver). This says nothing about
    whether its kernel compiler works: :func:`mesh2hrtf_io.backends.probe` tells that."""
    try:
        import pyopencl  # noqa: PLC0415
        return any(device.type & pyopencl.device_type.CPU
                   for platform in pyopencl.get_platforms() for device in platform.get_devices())
    except Exception:  # noqa: BLE001 - no pyopencl, no ICD loader, no platform
        return False


def set_backend(device: str) -> None:
    """Use ``device`` (numba, opencl or cuda) for the following solves of this process, without probing it (the
    probe's child and tests; the workflow goes through :func:`use_device`)."""
    if device not in DEVICES:
        raise Mesh2HrtfIoError(f"embedded device must be one of {', '.join(DEVICES)}; got {device!r}")
    if device == "opencl" and _device_state.get("opencl_blocked"):
        raise Mesh2HrtfIoError("the opencl backend must be chosen before the process's first solve (bempp-cl was "
                               "loaded without OpenCL); choose it first, or use numba")
    _device_state["device"] = device
    if device == "opencl":
        _bempp().DEFAULT_DEVICE_INTERFACE = "opencl"


def backend_choice_summary() -> dict:
    """What :func:`use_device` chose and why, with the seconds its probes took in this process (0 when cached)."""
    choice = _device_state.get("choice")
    if choice is None:
        return {"backend": current_backend(), "reason": "set directly", "probe_seconds": 0.0}
    return {"backend": choice.backend, "reason": choice.reason,
            "probe_seconds": round(sum(v.seconds for v in choice.verdicts if not v.cached), 2)}


def current_backend() -> str:
    """The backend the next solve uses (numba unless :func:`use_device` or :func:`set_backend` chose another)."""
    return str(_device_state["device"] or "numba")


def use_device(device: str = "auto", threads: int | None = None) -> str:
    """Choose the embedded solver's backend ('auto': cuda where a GPU passes its probe, else numba; 'opencl' and
    'cuda' only after their probe passed on this machine, :mod:`mesh2hrtf_io.backends`) and its CPU threads (None:
    all cores); call before the first solve of the process. Returns the backend chosen."""
    from .backends import CHOICES, choose_backend  # noqa: PLC0415

    if device not in CHOICES:
        raise Mesh2HrtfIoError(f"embedded device must be one of {', '.join(CHOICES)}; got {device!r}")
    if threads:
        import numba  # noqa: PLC0415

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
        # pocl reads its thread count once, when pyopencl first lists the platforms: set before it
        os.environ["POCL_MAX_PTHREAD_COUNT"] = str(int(threads))
    choice = choose_backend(device)
    set_backend(choice.backend)
    _device_state["choice"] = choice
    log.info("embedded solver: %s (%s)%s", choice.backend, choice.reason, f", {threads} thread(s)" if threads else "")
    return choice.backend


def _bempp():
    """bempp-cl's API with the chosen backend (:func:`use_device`; by default the fastest available), its
    import chatter (a missing Gmsh, which we never use), OpenCL compiler notes and per-operator timing lines
    silenced, and its import-time temporary folder removed at exit."""
    import atexit  # noqa: PLC0415
    import contextlib  # noqa: PLC0415
    import io  # noqa: PLC0415
    import shutil  # noqa: PLC0415

    import sys  # noqa: PLC0415

    if _device_state["device"] != "opencl" and "pyopencl" not in sys.modules:
        # bempp-cl imports pyopencl when it can; without the opencl backend nothing of pocl is loaded into this
        # process (its compiler aborts on some CPUs), and bempp-cl runs without OpenCL
        sys.modules["pyopencl"] = None
        _device_state["opencl_blocked"] = True
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import bempp_cl.api as bempp  # noqa: PLC0415
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise Mesh2HrtfIoError("the embedded solver needs bempp-cl: pip install bempp-cl") from exc
    if not getattr(bempp, "_ppm_configured", False):
        import warnings  # noqa: PLC0415

        warnings.filterwarnings("ignore", message="Non-empty compiler output")  # pyopencl's CompilerWarning
        # pocl's compiler would print "66 warnings generated." for every kernel build of bempp-cl: '-w' (an
        # OpenCL build option) keeps its warnings, which are about bempp-cl's sources, out of the user's terminal
        os.environ.setdefault("PYOPENCL_BUILD_OPTIONS", "-w")
        # bempp-cl's own kernels run only for the opt-in opencl backend (the right-hand sides and potentials);
        # numba's are compiled only when asked for
        bempp.DEFAULT_DEVICE_INTERFACE = "opencl" if _device_state["device"] == "opencl" else "numba"
        bempp.GLOBAL_PARAMETERS.quadrature.regular = REGULAR_QUADRATURE_ORDER
        bempp.GLOBAL_PARAMETERS.quadrature.singular = SINGULAR_QUADRATURE_ORDER
        _keep_opencl_kernels()
        _cache_grid_functions()
        atexit.register(shutil.rmtree, bempp.TMP_PATH, True)
        bempp._ppm_configured = True
    logging.getLogger("bempp").setLevel(logging.WARNING)  # its per-operator timing lines drown the progress
    return bempp


def _cache_grid_functions() -> None:
    """Let numba keep bempp-cl's compiled grid and space functions (element adjacency, the P1 degrees of freedom)
    on disk, beside bempp-cl in the environment: they take only arrays, so the next process reuses their machine
    code instead of compiling them again (studies/embedded_backends.py, first frequency)."""
    import importlib  # noqa: PLC0415

    from numba.core.registry import CPUDispatcher  # noqa: PLC0415

    for name in GRID_AND_SPACE_MODULES:
        try:
            module = importlib.import_module(name)
        except ImportError:  # pragma: no cover - another bempp-cl layout: compile in every process as before
            continue
        for function in vars(module).values():
            if isinstance(function, CPUDispatcher):
                try:
                    function.enable_caching()
                except Exception as exc:  # noqa: BLE001 - a read-only environment: compile in every process
                    log.debug("numba cannot cache %s: %s", function, exc)


def _keep_opencl_kernels() -> None:
    """Build each of bempp-cl's OpenCL kernels once per process. bempp-cl builds a kernel for every operator it
    assembles, although the wavenumber reaches the kernel as an argument, not in its source or build options:
    about 20 builds (0.1 s each, even from pyopencl's disk cache) per frequency. Kernels are kept by their source
    file, build options and precision."""
    try:
        import bempp_cl.core.opencl_kernels as kernels  # noqa: PLC0415
    except ImportError:  # pragma: no cover - bempp-cl without its OpenCL part
        return
    build = kernels.build_program
    if getattr(build, "_ppm_kept", False):
        return
    built: dict[tuple, object] = {}

    def build_once(assembly_function, options, precision, device_type="cpu"):
        key = (assembly_function, tuple(sorted((name, repr(value)) for name, value in options.items())),
               precision, device_type)
        if key not in built:
            built[key] = build(assembly_function, options, precision, device_type)
        return built[key]

    build_once._ppm_kept = True
    kernels.build_program = build_once


@dataclasses.dataclass(frozen=True)
class CostEstimate:
    """Predicted cost of the embedded solver for one frequency: peak memory (GB) and seconds."""

    n_vertices: int
    n_elements: int
    memory_gb_per_frequency: float
    seconds_per_frequency: float


def estimate_cost(n_vertices: int, n_elements: int, n_points: int, n_ear_elements: int = 1,
                  backend: str = "numba") -> CostEstimate:
    """Dense Burton–Miller cost model: two dense P1 operators (double layer, hypersingular) of complex128,
    the right-hand side only on the ear elements, assembled on a 2-core machine, an LU factorisation, plus the
    evaluation at ``n_points``. Constants measured on the example head (see SECONDS_PER_ENTRY). ``backend``
    'cuda': seconds and GPU memory of :mod:`mesh2hrtf_io.bem_arrays`'s model, measured on an H200."""
    if backend == "cuda":
        from . import bem_arrays  # noqa: PLC0415

        return CostEstimate(n_vertices, n_elements,
                            round(bem_arrays.gpu_memory_needed_bytes(n_vertices, bem_arrays.GPU_WORK_BUDGET_BYTES)
                                  / 1e9, 3),
                            round(bem_arrays.gpu_seconds_per_frequency(n_vertices, n_elements), 2))
    dense = 2 * n_vertices**2 + 2 * n_vertices * n_ear_elements
    memory = MEMORY_OVERHEAD * 16.0 * (dense + n_points * (n_vertices + n_ear_elements)) / 1e9
    seconds = SECONDS_PER_ENTRY * dense + LU_SECONDS_PER_CUBE * n_vertices**3 + 4e-8 * n_points * n_vertices + 2.0
    return CostEstimate(n_vertices, n_elements, round(memory, 3), round(seconds, 2))


def solve_pressure(vertices_m: np.ndarray, faces: np.ndarray, ear_elements: np.ndarray, points_m: np.ndarray,
                   frequency_hz: float, speed_of_sound_m_s: float, density_kg_m3: float,
                   velocity_m_s: float = EAR_VELOCITY_M_S) -> np.ndarray:
    """Complex sound pressure (Pa, e^{-iωt}) at `points_m` (n, 3) radiated by the vibrating ear elements.

    Parameters
    ----------
    vertices_m : (v, 3) float
        Head mesh in metres, outward normals (counter-clockwise seen from outside).
    faces : (m, 3) int
        Triangles.
    ear_elements : (e,) int
        Indices of the vibrating faces.
    points_m : (n, 3) float
        Evaluation points in metres, outside the head.
    """
    return solve_sources(vertices_m, faces, [(ear_elements, velocity_m_s)], points_m, frequency_hz,
                         speed_of_sound_m_s, density_kg_m3)[0]


def solve_sources(vertices_m: np.ndarray, faces: np.ndarray, sources: list[tuple[np.ndarray, float]],
                  points_m: np.ndarray, frequency_hz: float, speed_of_sound_m_s: float,
                  density_kg_m3: float) -> list[np.ndarray]:
    """Pressure (Pa, e^{-iωt}) at `points_m` for each source, a source being (ear element indices, normal
    velocity in m/s); the sources are solved one at a time as in Mesh2HRTF (reciprocity: one per ear).

    The Burton-Miller system matrix does not depend on the source: it is assembled and LU-factorised
    once per frequency and applied to every source's right-hand side (a direct solve: no iteration that
    could stall at high frequencies on coarse meshes).
    """
    bempp = _bempp()
    backend = current_backend()
    k = 2.0 * np.pi * frequency_hz / speed_of_sound_m_s
    # each source's vibrating elements form a segment of their own (1, 2, ...); the prescribed velocity lives
    # only there, so the right-hand side operators are (vertices x ear elements), not dense
    segments = np.zeros(len(faces), dtype=np.uint32)
    for index, (elements, _) in enumerate(sources):
        if np.any(segments[np.asarray(elements)]):
            raise Mesh2HrtfIoError("two sources share vibrating elements; give each ear its own elements")
        segments[np.asarray(elements)] = EAR_SEGMENT + index
    from . import bem_arrays, burton_miller  # noqa: PLC0415 - numba's import and compiled kernels only when solving

    grid, p1, mass, far_geometry, touching, arrays = _surface(bempp, vertices_m, faces, segments)
    coupling = 1j / k  # Burton-Miller coupling for outgoing e^{ikr} waves
    start = time.perf_counter()
    array_sources = [(np.asarray(elements, np.int64), float(velocity)) for elements, velocity in sources]
    if backend == "cuda":
        # everything on the GPU: the same array code as the CPU twin (bem_arrays.py)
        budget = bem_arrays.gpu_work_budget(arrays.dof_count)  # a clear error when the head does not fit
        pressures = bem_arrays.solve_sources_arrays(_device_surface(arrays, "cupy"), array_sources, points_m,
                                                    frequency_hz, speed_of_sound_m_s, density_kg_m3,
                                                    budget_bytes=budget)
    else:
        # coupling * W - K in one pass for both operators (burton_miller.py): the element pairs sharing no vertex
        # with bempp-cl's Gauss rule, the touching ones with its singular rule; equal to bempp-cl's dense assembly
        system = burton_miller.assemble_far_pairs(far_geometry, k, coupling)
        burton_miller.add_singular_pairs(system, touching, far_geometry, k, coupling)
        mass_rows, mass_columns, mass_values = mass
        np.add.at(system, (mass_rows, mass_columns), 0.5 * mass_values)
        if backend == "opencl":
            pressures = _opencl_sources(bempp, grid, p1, system, segments, sources, points_m, frequency_hz, k,
                                        coupling, density_kg_m3)
        else:
            pressures = bem_arrays.solve_sources_arrays(_device_surface(arrays, "numpy"), array_sources, points_m,
                                                        frequency_hz, speed_of_sound_m_s, density_kg_m3,
                                                        system=system, far_geometry=far_geometry)
    log.info("%.0f Hz: solved %d unknowns for %d source(s) in %.1f s (%s)", frequency_hz, p1.global_dof_count,
             len(sources), time.perf_counter() - start, backend)
    return pressures


def _opencl_sources(bempp, grid, p1, system, segments, sources, points_m, frequency_hz, k, coupling,
                    density_kg_m3) -> list[np.ndarray]:
    """The opt-in opencl backend: the right-hand sides and the potentials by bempp-cl's OpenCL kernels."""
    import scipy.linalg  # noqa: PLC0415

    from bempp_cl.api.operators.boundary import helmholtz  # noqa: PLC0415
    from bempp_cl.api.operators.potential import helmholtz as helmholtz_potential  # noqa: PLC0415

    factors = scipy.linalg.lu_factor(system, overwrite_a=True, check_finite=False)
    points = np.asarray(points_m, np.float64).T.copy()
    double_layer_potential = helmholtz_potential.double_layer(p1, points, k)
    pressures = []
    for index, (_, velocity_m_s) in enumerate(sources):
        dp0 = bempp.function_space(grid, "DP", 0, segments=[EAR_SEGMENT + index])
        # Euler's equation with e^{-iωt}: dp/dn = iωρ v_n on the vibrating elements, 0 elsewhere (rigid)
        normal_derivative = 1j * 2.0 * np.pi * frequency_hz * density_kg_m3 * velocity_m_s
        neumann = bempp.GridFunction(dp0, coefficients=np.full(dp0.global_dof_count, normal_derivative,
                                                               dtype=np.complex128))
        rhs_operator = -(helmholtz.single_layer(dp0, p1, p1, k) + coupling * helmholtz.adjoint_double_layer(dp0, p1, p1, k))
        rhs = (rhs_operator * neumann).projections(p1) - coupling * 0.5 * normal_derivative * _p1_load(
            grid, p1, np.flatnonzero(segments == EAR_SEGMENT + index))
        coefficients = scipy.linalg.lu_solve(factors, rhs, check_finite=False)
        if not np.isfinite(coefficients).all():
            raise Mesh2HrtfIoError(f"the BEM system at {frequency_hz:g} Hz is singular (degenerate mesh?)")
        surface_pressure = bempp.GridFunction(p1, coefficients=coefficients)
        field = (double_layer_potential * surface_pressure
                 - helmholtz_potential.single_layer(dp0, points, k) * neumann)
        pressures.append(np.asarray(field).ravel())
    return pressures


def _p1_load(grid, p1, elements: np.ndarray) -> np.ndarray:
    """Integral of each P1 hat function over the given elements (m^2): A/3 per corner of each triangle; the weak
    form of identity(DP0, P1, P1) applied to 1 on those elements."""
    load = np.zeros(p1.global_dof_count)
    np.add.at(load, p1.local2global[elements].ravel(),
              (p1.local_multipliers[elements] * grid.volumes[elements, None] / 3.0).ravel())
    return load


_surface_state: dict[str, object] = {"key": None, "surface": None}


def _surface(bempp, vertices_m: np.ndarray, faces: np.ndarray, segments: np.ndarray):
    """bempp's grid of the head (metres), its P1 space, its P1 mass terms (:func:`bem_arrays.mass_terms`) and the geometry of its
    far and touching element pairs (:mod:`burton_miller`), kept while the same head is solved frequency after
    frequency: building the grid's geometry takes about a second on a demo head."""
    import hashlib  # noqa: PLC0415

    vertices = np.ascontiguousarray(vertices_m, np.float64)
    triangles = np.ascontiguousarray(faces, np.uint32)
    key = hashlib.blake2b(vertices.tobytes() + triangles.tobytes() + np.ascontiguousarray(segments).tobytes(),
                          digest_size=16).hexdigest()
    if _surface_state["key"] != key:
        from . import bem_arrays, burton_miller  # noqa: PLC0415

        grid = bempp.Grid(vertices.T.copy(), triangles.T.copy(), domain_indices=segments)
        p1 = bempp.function_space(grid, "P", 1)
        far = burton_miller.far_field_geometry(grid, p1, REGULAR_QUADRATURE_ORDER)
        touching = burton_miller.singular_pairs(grid, p1, SINGULAR_QUADRATURE_ORDER)
        arrays = bem_arrays.from_geometry(far, touching)
        _surface_state["surface"] = (grid, p1, bem_arrays.mass_terms(arrays), far, touching, arrays)
        _surface_state["key"] = key
        _surface_state["device_surfaces"] = {}
    return _surface_state["surface"]


def _device_surface(arrays, backend: str):
    """The surface's arrays on ``backend`` ('numpy' or 'cupy'), kept with the surface."""
    from . import bem_arrays  # noqa: PLC0415

    kept = _surface_state.setdefault("device_surfaces", {})
    if backend not in kept:
        kept[backend] = bem_arrays.DeviceSurface(
            arrays, bem_arrays.cupy_backend() if backend == "cupy" else bem_arrays.numpy_backend())
    return kept[backend]


def free_field_reference(points_m: np.ndarray, frequency_hz: float, source_area_m2: float,
                         speed_of_sound_m_s: float, density_kg_m3: float, velocity_m_s: float = EAR_VELOCITY_M_S,
                         radius_m: float | None = None) -> np.ndarray:
    """Pressure of a point source at the origin with the ear's volume velocity, as Mesh2HRTF references
    (e^{-iωt}; at the smallest radius of the points unless `radius_m` is given)."""
    r = float(np.min(np.linalg.norm(points_m, axis=1))) if radius_m is None else radius_m
    volume_flow = velocity_m_s * source_area_m2
    k = 2.0 * np.pi * frequency_hz / speed_of_sound_m_s
    value = -1j * density_kg_m3 * 2.0 * np.pi * frequency_hz * volume_flow / (4.0 * np.pi) * np.exp(1j * k * r) / r
    return np.full(len(points_m), value)
