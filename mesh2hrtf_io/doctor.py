"""Which BEM solver is usable here, and why not: ``m2h doctor``."""
from __future__ import annotations

import os
import subprocess

from .backends import installed_module
from .numcalc import INSTALL_HINT, NumCalcError, find_numcalc


def numcalc_status(configured: str | os.PathLike | None = None) -> dict:
    """NumCalc: found (configured path, PATH, or .venv/bin), runs, and knows -estimate_ram (Mesh2HRTF >= 1.2)."""
    try:
        binary = find_numcalc(configured)
    except NumCalcError as exc:
        return {"usable": False, "why": str(exc)}
    try:
        result = subprocess.run([str(binary), "-h"], capture_output=True, text=True, timeout=30,
                                cwd=os.path.dirname(binary))
    except (OSError, subprocess.TimeoutExpired) as exc:
        return {"usable": False, "path": str(binary), "why": f"{binary} does not run ({exc}); {INSTALL_HINT}"}
    if "-estimate_ram" not in result.stdout + result.stderr:
        return {"usable": False, "path": str(binary),
                "why": f"{binary} does not know -estimate_ram: not NumCalc from Mesh2HRTF 1.2.x; {INSTALL_HINT}"}
    return {"usable": True, "path": str(binary), "why": "runs and knows -estimate_ram (Mesh2HRTF 1.2.x)"}


def embedded_status() -> dict:
    """The embedded solver and each of its backends (numba, opencl, cuda): installed, and the cached verdict of its
    probe on this machine (mesh2hrtf_io/backends.py; None: not probed yet), and what ``auto`` would choose now
    without probing. Nothing is imported that could abort: the probes run in child processes."""
    from .backends import BACKENDS, CACHE_FILE, auto_candidates, cache_dir, cached_verdict  # noqa: PLC0415

    missing = [name for name in ("bempp_cl", "numba") if not installed_module(name)]
    if missing:
        return {"usable": False, "why": f"{', '.join(missing)} not installed; run scripts/setup.sh"}
    needs = {"numba": (), "opencl": ("pyopencl",), "cuda": ("cupy",)}
    states = {}
    for backend in BACKENDS:
        absent = [name for name in needs[backend] if not installed_module(name)]
        verdict = None if backend == "numba" or absent else cached_verdict(backend)
        states[backend] = {
            "installed": not absent,
            "usable": backend == "numba" or bool(verdict and verdict.ok),
            "verdict": verdict.as_dict() if verdict else None,
            "why": ("always: the fallback" if backend == "numba" else
                    f"{', '.join(absent)} not installed" + (" (pip install -e '.[gpu]')" if backend == "cuda" else "")
                    if absent else (verdict.reason if verdict else "not probed yet on this machine "
                                    "(probed on first use, or now: m2h doctor --probe)"))}
    candidates = [c for c in auto_candidates() if states[c]["verdict"] is None or states[c]["usable"]]
    return {"usable": True, "why": "bempp-cl installed; dense, suits meshes up to ~10,000 vertices on a CPU",
            "backends": states, "auto": candidates[0] if candidates else "numba",
            "verdict_cache": str(cache_dir() / CACHE_FILE)}


def doctor(configured_numcalc: str | os.PathLike | None = None, probe: bool = False) -> dict:
    """Status of both solvers and the one the workflow's default (hrtf.solver: numcalc) would use. ``probe``: probe
    the embedded solver's optional backends (opencl, and cuda where CuPy is installed) now, in child processes,
    instead of only reporting cached verdicts."""
    if probe:
        from .backends import probe as probe_backend  # noqa: PLC0415

        for backend in ("opencl", "cuda"):
            if installed_module({"opencl": "pyopencl", "cuda": "cupy"}[backend]):
                probe_backend(backend)
    numcalc, embedded = numcalc_status(configured_numcalc), embedded_status()
    advice = ("NumCalc is ready (hrtf.solver: numcalc)" if numcalc["usable"] else
              "only the embedded solver is usable: set hrtf.solver: embedded (small meshes), or install NumCalc"
              if embedded["usable"] else "no solver is usable")
    return {"numcalc": numcalc, "embedded": embedded, "advice": advice}
