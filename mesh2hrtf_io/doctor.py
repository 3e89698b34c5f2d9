"""Which BEM solver is usable here, and why not: ``m2h doctor``."""
from __future__ import annotations

import importlib.util
import os
import subprocess

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
    """The embedded solver: bempp-cl and numba installed (found without importing them: bempp-cl's import
    compiles kernels and prints chatter)."""
    missing = [name for name in ("bempp_cl", "numba") if importlib.util.find_spec(name) is None]
    if missing:
        return {"usable": False, "why": f"{', '.join(missing)} not installed; run scripts/setup.sh"}
    return {"usable": True, "why": "bempp-cl installed; dense, suits meshes up to ~10,000 vertices"}


def doctor(configured_numcalc: str | os.PathLike | None = None) -> dict:
    """Status of both solvers and the one the workflow's default (hrtf.solver: numcalc) would use."""
    numcalc, embedded = numcalc_status(configured_numcalc), embedded_status()
    advice = ("NumCalc is ready (hrtf.solver: numcalc)" if numcalc["usable"] else
              "only the embedded solver is usable: set hrtf.solver: embedded (small meshes), or install NumCalc"
              if embedded["usable"] else "no solver is usable")
    return {"numcalc": numcalc, "embedded": embedded, "advice": advice}
