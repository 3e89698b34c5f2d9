"""Which backend of the embedded solver runs on this machine: each optional backend is probed in a child process
(so a native library that aborts cannot take the run down), the verdict is cached per machine and library versions.

Backends (config ``hrtf.embedded_device``):

- ``numba``: the project's own numba pass assembles the Burton–Miller matrix, LAPACK factorises it, NumPy
  (:mod:`mesh2hrtf_io.bem_arrays`) computes the right-hand sides and the pressure at the evaluation points. Needs
  no probe: it is the fallback everywhere.
- ``opencl``: as numba, but bempp-cl's OpenCL kernels (pocl on the CPU) compute the right-hand sides and the
  potentials. Opt-in: pocl's kernel compiler aborts the process on some CPUs (``LLVM ERROR: Cannot select ...
  fsqrt`` for a double8 on AMD Zen 4), and the numba backend is as fast (studies/embedded_backends.py).
- ``cuda``: everything per frequency on an NVIDIA GPU through CuPy (the same array code as the CPU twin).
- ``auto``: cuda where a CUDA GPU is seen and its probe passes, else numba.

A probe is ``python -m mesh2hrtf_io.backend_probe <backend> --out FILE`` (:mod:`mesh2hrtf_io.backend_probe`): a kernel with the vector math the backend's
kernels use, and a one-frequency solve of a small sphere compared with the numba backend's answer. A child that
dies by a signal, exits non-zero, or answers wrong is a failed probe, whose reason is its last stderr line.
"""
from __future__ import annotations

import dataclasses
import datetime
import hashlib
import importlib.metadata
import json
import logging
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .errors import Mesh2HrtfIoError

log = logging.getLogger(__name__)
BACKENDS = ("numba", "opencl", "cuda")
CHOICES = ("auto", *BACKENDS)
#: Libraries whose versions decide a verdict: a change of any of them probes again.
PROBED_LIBRARIES = {
    "opencl": ("pyopencl", "pocl-binary-distribution", "bempp-cl", "numba", "llvmlite", "numpy"),
    "cuda": ("cupy-cuda12x", "cupy-cuda13x", "cupy-cuda11x", "cupy", "numpy", "scipy"),
}
#: Largest relative difference of the probe sphere's pressures against the numba backend (both in double precision
#: with the same quadrature: measured 1e-14 on this machine).
PROBE_TOLERANCE = 1e-8
PROBE_TIMEOUT_S = 900.0
CACHE_FILE = "embedded_backend_probes.json"


@dataclasses.dataclass(frozen=True)
class Verdict:
    """A probe's result: whether ``backend`` works here, why (its last stderr line when it failed), its seconds,
    when it was probed and whether it came from the cache."""

    backend: str
    ok: bool
    reason: str
    seconds: float
    probed_at: str
    cached: bool = False
    details: dict = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def cache_dir() -> Path:
    """The user's cache folder for verdicts: $PPM_HRTF_CACHE_DIR, else $XDG_CACHE_HOME/ppm-hrtf, else
    ~/.cache/ppm-hrtf."""
    if os.environ.get("PPM_HRTF_CACHE_DIR"):
        return Path(os.environ["PPM_HRTF_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ppm-hrtf"


def machine_facts() -> dict:
    """What a verdict depends on about the machine: architecture, CPU model and instruction-set flags, Python."""
    model, flags = "", ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and not model:
                model = value.strip()
            elif key.strip() in ("flags", "Features") and not flags:
                flags = " ".join(sorted(value.split()))
    except OSError:
        pass
    model = model or platform.processor()
    return {"machine": platform.machine(), "cpu": model, "cpu_flags": hashlib.sha256(flags.encode()).hexdigest()[:16],
            "python": platform.python_version()}


def library_versions(backend: str) -> dict:
    """Installed versions of the libraries a backend's verdict depends on (None: not installed)."""
    versions = {}
    for name in PROBED_LIBRARIES.get(backend, ()):
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def verdict_key(backend: str) -> str:
    facts = {"backend": backend, **machine_facts(), "versions": library_versions(backend)}
    return hashlib.sha256(json.dumps(facts, sort_keys=True).encode()).hexdigest()[:24]


def _read_cache(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def _write_cache(path: Path, entries: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".part") as handle:
        json.dump(entries, handle, indent=2)
    os.replace(handle.name, path)


def cached_verdict(backend: str) -> Verdict | None:
    """The cached verdict of ``backend`` for this machine and these library versions, or None."""
    entry = _read_cache(cache_dir() / CACHE_FILE).get(verdict_key(backend))
    if not entry:
        return None
    return Verdict(**{**entry, "cached": True})


def probe(backend: str, *, command: list[str] | None = None, timeout_s: float = PROBE_TIMEOUT_S,
          use_cache: bool = True) -> Verdict:
    """Probe ``backend`` in a child process (``command``: another probe program, for tests; ``{out}`` in it is the
    path of the verdict file it writes) unless a verdict for
    this machine and library versions is cached; cache the new verdict."""
    if backend == "numba":
        return Verdict("numba", True, "the fallback: no native code but numba's, always probed by the tests", 0.0,
                       _now(), cached=False)
    if backend not in BACKENDS:
        raise Mesh2HrtfIoError(f"unknown embedded backend {backend!r}; one of {', '.join(BACKENDS)}")
    if use_cache:
        known = cached_verdict(backend)
        if known is not None:
            return known
    verdict = _run_probe(backend, command, timeout_s)
    if use_cache:
        path = cache_dir() / CACHE_FILE
        entries = _read_cache(path)
        entry = {key: value for key, value in verdict.as_dict().items() if key != "cached"}
        entry["details"] = {**verdict.details, "machine": machine_facts(), "versions": library_versions(backend)}
        entries[verdict_key(backend)] = entry
        try:
            _write_cache(path, entries)
        except OSError as exc:  # a read-only home: probe again next time
            log.warning("cannot cache the %s probe's verdict in %s: %s", backend, path, exc)
    return verdict


def no_core_dumps() -> None:
    """In this process (a probe child, before it tries a native backend that may abort): no core file, and not
    dumpable at all, so that neither the kernel nor a core_pattern pipe (systemd-coredump, apport) writes gigabytes of
    a driver's address space when the backend aborts (pocl on an unsupported CPU: minutes of system time). POSIX only;
    elsewhere nothing happens."""
    try:
        import resource  # noqa: PLC0415

        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    except (ImportError, ValueError, OSError):
        pass
    if sys.platform.startswith("linux"):
        import ctypes  # noqa: PLC0415

        try:
            ctypes.CDLL(None, use_errno=True).prctl(4, 0, 0, 0, 0)  # PR_SET_DUMPABLE = 4, off
        except (OSError, AttributeError):
            pass


def _run_probe(backend: str, command: list[str] | None, timeout_s: float) -> Verdict:
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "verdict.json"
        # another probe program (tests) gets the verdict file's path where its arguments say {out}
        argv = ([part.replace("{out}", str(out)) for part in command] if command else
                [sys.executable, "-m", "mesh2hrtf_io.backend_probe", backend, "--out", str(out)])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                                            os.environ.get("PYTHONPATH", "")]))
        try:
            # the core-file limit of 0 passes through exec to the child; the probe module also turns dumping off
            done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout_s, env=env,
                                  stdin=subprocess.DEVNULL, preexec_fn=no_core_dumps if os.name == "posix" else None)
        except subprocess.TimeoutExpired:
            return Verdict(backend, False, f"the probe gave no answer in {timeout_s:.0f} s",
                           time.perf_counter() - start, _now())
        seconds = round(time.perf_counter() - start, 2)
        last = _last_line(done.stderr) or _last_line(done.stdout)
        if done.returncode < 0:
            name = signal.Signals(-done.returncode).name if -done.returncode in signal.valid_signals() else "?"
            return Verdict(backend, False, f"the probe died by signal {name}: {last or '(no stderr)'}", seconds, _now())
        if done.returncode != 0:
            return Verdict(backend, False, f"the probe exited with status {done.returncode}: {last or '(no stderr)'}",
                           seconds, _now())
        try:
            answer = json.loads(out.read_text())
        except (OSError, ValueError):
            return Verdict(backend, False, f"the probe wrote no verdict: {last or '(no output)'}", seconds, _now())
    return Verdict(backend, bool(answer.get("ok")), str(answer.get("reason", "")), seconds, _now(),
                   details=answer.get("details", {}))


def _last_line(text: str | None) -> str:
    lines = [line.strip() for line in (text or "").splitlines() if line.strip()]
    return lines[-1] if lines else ""


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def installed_module(name: str) -> bool:
    """Whether a top-level module is installed, looked up on sys.path (not in this process's loaded modules: the
    embedded solver keeps pyopencl out of processes that do not use it)."""
    import importlib.machinery  # noqa: PLC0415

    return importlib.machinery.PathFinder.find_spec(name) is not None


def gpu_seen() -> bool:
    """A CUDA GPU may be here: CuPy is installed and the driver's device node or nvidia-smi exists (nothing is
    initialised: the probe does that in its child)."""
    import shutil  # noqa: PLC0415

    if not installed_module("cupy"):
        return False
    return Path("/dev/nvidia0").exists() or shutil.which("nvidia-smi") is not None


def auto_candidates() -> tuple[str, ...]:
    """The backends ``auto`` tries, fastest first, before numba: cuda where a GPU is seen."""
    return ("cuda",) if gpu_seen() else ()


@dataclasses.dataclass(frozen=True)
class Choice:
    backend: str
    reason: str
    verdicts: tuple[Verdict, ...] = ()


def choose_backend(requested: str = "auto", *, candidates: tuple[str, ...] | None = None,
                   probe_command: list[str] | None = None, timeout_s: float = PROBE_TIMEOUT_S) -> Choice:
    """The backend to solve with. ``numba``: numba. ``opencl``/``cuda``: that one if its probe passes, else a
    :class:`Mesh2HrtfIoError` naming the probe's failure and the setting to change. ``auto``: the first of
    ``candidates`` (default :func:`auto_candidates`) whose probe passes, else numba, with one log line saying why."""
    if requested not in CHOICES:
        raise Mesh2HrtfIoError(f"hrtf.embedded_device must be one of {', '.join(CHOICES)}; got {requested!r}")
    if requested == "numba":
        return Choice("numba", "asked for")
    if requested != "auto":
        verdict = probe(requested, command=probe_command, timeout_s=timeout_s)
        if not verdict.ok:
            needs = (" (the cuda backend needs an NVIDIA GPU and CuPy: pip install -e '.[gpu]')"
                     if requested == "cuda" else "")
            raise Mesh2HrtfIoError(
                f"embedded solver backend {requested!r} failed its probe on this machine ({verdict.reason}){needs}; set "
                f"hrtf.embedded_device: numba (or auto) in the config, or --config hrtf='{{embedded_device: numba}}'"
                f" (verdict cached in {cache_dir() / CACHE_FILE}; delete it to probe again)")
        return Choice(requested, f"asked for; probe passed ({verdict.reason})", (verdict,))
    verdicts = []
    for candidate in (auto_candidates() if candidates is None else candidates):
        verdict = probe(candidate, command=probe_command, timeout_s=timeout_s)
        verdicts.append(verdict)
        if verdict.ok:
            return Choice(candidate, f"auto: {candidate} passed its probe", tuple(verdicts))
        log.warning("embedded solver: %s is not usable here, using numba instead: %s", candidate, verdict.reason)
    why = "; ".join(f"{v.backend}: {v.reason}" for v in verdicts) or "no faster backend here"
    return Choice("numba", f"auto: numba ({why})", tuple(verdicts))
