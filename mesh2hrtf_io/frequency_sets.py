"""Frequency sets of HRTF projects (Hz): linear grids, ERB-spaced and warped sets, explicit lists, presets.

A linear grid Δf, 2Δf, ..., f_max gives HRIRs by an inverse DFT as Output2HRTF does; any other set is
solved as it is (NumCalc's load frequency curve takes arbitrary lists) and its HRIRs are rebuilt
(:mod:`mesh2hrtf_io.sparse_hrtf`). Presets live in ``mesh2hrtf_io/data/frequency_sets.yaml``.
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import yaml

from hrtf_dsp.erb import erb_number_to_freq, freq_to_erb_number

from .errors import Mesh2HrtfIoError

PRESETS_FILE = Path(__file__).with_name("data") / "frequency_sets.yaml"
FEWEST_FOR_REBUILD = 8
_SCALE_KEYS = {"erb": {"min", "max", "step_erb"}, "warped": {"min", "max", "count", "corner_hz"}}


@functools.lru_cache(maxsize=1)
def presets() -> dict[str, dict]:
    """The named sets of frequency_sets.yaml (name -> spec with a 'description')."""
    return yaml.safe_load(PRESETS_FILE.read_text())


def frequency_list(minimum_hz: float, maximum_hz: float, step_hz: float) -> np.ndarray:
    """minimum, minimum + step, ..., up to maximum (Hz); for exact HRIRs use minimum = step."""
    if not 0 < minimum_hz <= maximum_hz or step_hz <= 0:
        raise Mesh2HrtfIoError(f"frequencies need 0 < min <= max and step > 0, got {minimum_hz}, {maximum_hz}, {step_hz}")
    return minimum_hz + step_hz * np.arange(int(np.floor((maximum_hz - minimum_hz) / step_hz + 1e-9)) + 1)


def warped_frequencies(minimum_hz: float, maximum_hz: float, count: int, corner_hz: float) -> np.ndarray:
    """``count`` frequencies from min to max (Hz) equally spaced in ln(1 + f / corner_hz)."""
    if not 0 < minimum_hz < maximum_hz or count < 2 or corner_hz <= 0:
        raise Mesh2HrtfIoError(f"a warped set needs 0 < min < max, count >= 2 and corner_hz > 0; got min "
                               f"{minimum_hz}, max {maximum_hz}, count {count}, corner_hz {corner_hz}")
    x = np.linspace(np.log1p(minimum_hz / corner_hz), np.log1p(maximum_hz / corner_hz), int(count))
    return corner_hz * np.expm1(x)


def erb_frequencies(minimum_hz: float, maximum_hz: float, step_erb: float) -> np.ndarray:
    """Frequencies from min (Hz) in steps of ``step_erb`` on the ERB-number scale, up to max."""
    if not 0 < minimum_hz < maximum_hz or step_erb <= 0:
        raise Mesh2HrtfIoError(f"an ERB set needs 0 < min < max and step_erb > 0; got {minimum_hz}, {maximum_hz}, {step_erb}")
    low, high = freq_to_erb_number(np.float64(minimum_hz)), freq_to_erb_number(np.float64(maximum_hz))
    return erb_number_to_freq(low + step_erb * np.arange(int(np.floor((high - low) / step_erb + 1e-9)) + 1))


def check_frequency_set(frequencies_hz, source: str = "frequency set", nyquist_hz: float | None = None,
                        fewest: int = 1) -> np.ndarray:
    """The set as a float array, or a :class:`Mesh2HrtfIoError` naming ``source`` and the problem:
    not finite, not above 0 Hz, unsorted, duplicates, above Nyquist, fewer than ``fewest``."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    if f.ndim != 1 or f.size == 0:
        raise Mesh2HrtfIoError(f"{source}: give a non-empty list of frequencies in Hz")
    if not np.isfinite(f).all():
        raise Mesh2HrtfIoError(f"{source}: frequencies must be finite (found NaN or inf)")
    if (f <= 0).any():
        raise Mesh2HrtfIoError(f"{source}: frequencies must lie above 0 Hz (NumCalc drops 0 Hz; the rebuild "
                               f"sets 0 Hz itself), got {f[f <= 0].tolist()}")
    steps = np.diff(f)
    if (steps == 0).any():
        raise Mesh2HrtfIoError(f"{source}: duplicate frequencies {sorted(set(f[1:][steps == 0].tolist()))} Hz; "
                               "list each once")
    if (steps < 0).any():
        raise Mesh2HrtfIoError(f"{source}: frequencies must be strictly increasing, sorted in increasing order "
                               f"(first drop after {f[int(np.argmax(steps < 0))]:g} Hz)")
    if nyquist_hz is not None and f[-1] > nyquist_hz * (1 + 1e-9):
        raise Mesh2HrtfIoError(f"{source}: {f[-1]:g} Hz lies above the Nyquist frequency {nyquist_hz:g} Hz of "
                               f"the output; drop it or use a sampling rate above {2 * f[-1]:g} Hz")
    if f.size < fewest:
        raise Mesh2HrtfIoError(f"{source}: {f.size} frequencies are too few; rebuilding HRIRs needs at least {fewest}")
    return f


def is_linear_grid(frequencies_hz) -> bool:
    """True for Δf, 2Δf, ..., KΔf (K >= 2): HRIRs follow by an inverse DFT, no rebuild needed."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    return bool(f.size >= 2 and f[0] > 0 and np.allclose(f, f[0] * np.arange(1, f.size + 1), rtol=0, atol=1e-6 * f[0]))


def frequencies_from_spec(spec: dict | str, source: str = "config hrtf.frequencies_hz") -> np.ndarray:
    """The frequencies (Hz, increasing, rounded to NumCalc's 0.01 Hz) of a set given as in frequency_sets.yaml,
    or of the preset named by a string."""
    if isinstance(spec, str):
        spec = {"preset": spec}
    if not isinstance(spec, dict):
        raise Mesh2HrtfIoError(f"{source}: give a mapping ({{min, max, step}}, {{preset: NAME}}, {{scale: ..}} or "
                               f"{{list: [..]}}), got {spec!r}")
    if "preset" in spec:
        name = spec["preset"]
        if name not in presets():
            raise Mesh2HrtfIoError(f"{source}: unknown preset {name!r}; known: {', '.join(sorted(presets()))} "
                                   f"({PRESETS_FILE})")
        return frequencies_from_spec({k: v for k, v in presets()[name].items() if k != "description"},
                                     f"{source} (preset {name})")
    if "list" in spec:
        f = check_frequency_set(spec["list"], source)
    elif "scale" in spec:
        scale = spec["scale"]
        if scale not in _SCALE_KEYS:
            raise Mesh2HrtfIoError(f"{source}: scale must be one of {sorted(_SCALE_KEYS)}, got {scale!r}")
        missing = _SCALE_KEYS[scale] - set(spec)
        if missing:
            raise Mesh2HrtfIoError(f"{source}: a {scale} set needs the keys {sorted(missing)}")
        if scale == "erb":
            core = erb_frequencies(spec["min"], spec["max"], spec["step_erb"])
        else:
            core = warped_frequencies(spec["min"], spec["max"], spec["count"], spec["corner_hz"])
        extra = np.asarray(spec.get("extra", []), dtype=np.float64)
        if ((extra >= spec["min"]) & (extra <= spec["max"])).any():
            raise Mesh2HrtfIoError(f"{source}: extra frequencies must lie outside [{spec['min']}, {spec['max']}] Hz")
        f = np.sort(np.concatenate([core, extra]))
    elif {"min", "max", "step"} <= set(spec):
        f = frequency_list(spec["min"], spec["max"], spec["step"])
    else:
        raise Mesh2HrtfIoError(f"{source}: cannot read {spec!r}; give {{min, max, step}}, {{preset: NAME}}, "
                               "{scale: erb|warped, ...} or {list: [...]}")
    return check_frequency_set(np.round(f, 2), source)


def describe_set(frequencies_hz) -> str:
    """One line for reports: count, range and whether HRIRs are exact or rebuilt."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    kind = (f"linear, {f[0]:g} Hz steps (exact HRIRs)" if is_linear_grid(f) else
            "sparse set (HRIRs rebuilt: magnitude PCHIP over ERB number, minimum phase plus each response's delay)")
    return f"{f.size} frequencies, {f[0]:g} Hz to {f[-1]:g} Hz, {kind}"
