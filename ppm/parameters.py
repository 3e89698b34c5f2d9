"""The 144 named parameters of the parametric pinna model and their conversions.

Units: locations in millimetres and rotations in degrees (Euler, Blender order 'ZYX'), both pose
transforms in the bone's own frame relative to the rest pose; scales are factors (1 = rest);
shape-key weights are dimensionless. Names follow ppm_spec.md, e.g. `Location_Tragus-Start_X`,
`Rotation_Helix_up-End_Z`, `Scale_Lobulus-Bendy`, `Scale_Size-Bendy_Y`, `Shape_key_Cavum_conchae-Depth`.
"""
from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import yaml

from core.atomic import write_text_atomic
from .errors import PpmError

AXES = ("X", "Y", "Z")


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One degree of freedom: its name, the bone or shape key it drives, and its range.

    `kind` is 'location' (mm), 'rotation' (deg), 'scale' (factor) or 'shape_key' (weight);
    `target` is the bone name or the shape-key name; `axis` is 0, 1, 2 for X, Y, Z, or None.
    `lower`/`upper` bound what an alignment may reach; `typical_lower`/`typical_upper` are the
    spread between listeners that random ears are drawn from (inside the bounds).
    """

    name: str
    kind: str
    target: str
    axis: int | None
    default: float
    lower: float
    upper: float
    typical_lower: float
    typical_upper: float

    @property
    def unit(self) -> str:
        return {"location": "mm", "rotation": "deg", "scale": "factor", "shape_key": "weight"}[self.kind]


@lru_cache(maxsize=1)
def model_layout() -> dict:
    """The parsed `ppm/data/parameters.yaml` (curves, shape keys, bounds)."""
    text = resources.files("ppm").joinpath("data/parameters.yaml").read_text(encoding="utf-8")
    return yaml.safe_load(text)


def _ranges(layout: dict, group: str, key: str) -> tuple[float, float, float, float]:
    """(lower, upper, typical_lower, typical_upper) of one parameter group from parameters.yaml."""
    lower, upper = map(float, layout["bounds"][group][key])
    typical = layout.get("typical", {}).get(group, {}).get(key, (lower, upper))
    typical_lower, typical_upper = map(float, typical)
    if not lower <= typical_lower <= typical_upper <= upper:
        raise PpmError(f"ppm/data/parameters.yaml: typical {group}.{key} [{typical_lower}, {typical_upper}] "
                       f"must lie inside the bounds [{lower}, {upper}]; narrow the typical range or widen "
                       "the bounds")
    return lower, upper, typical_lower, typical_upper


def _vector_specs(kind: str, bone: str, ranges: tuple[float, ...], default: float) -> list[ParameterSpec]:
    stem = {"location": "Location", "rotation": "Rotation", "scale": "Scale"}[kind]
    return [ParameterSpec(f"{stem}_{bone}_{axis}", kind, bone, i, default, *ranges)
            for i, axis in enumerate(AXES)]


@lru_cache(maxsize=1)
def parameter_specs() -> tuple[ParameterSpec, ...]:
    """All 144 parameters in their canonical order: parent bone, then per curve, then shape keys."""
    layout = model_layout()
    parent = layout["parent_bone"]
    specs = (_vector_specs("location", parent, _ranges(layout, "parent", "location_mm"), 0.0)
             + _vector_specs("rotation", parent, _ranges(layout, "parent", "rotation_deg"), 0.0)
             + _vector_specs("scale", parent, _ranges(layout, "parent", "scale"), 1.0))
    control_location = _ranges(layout, "control", "location_mm")
    control_rotation = _ranges(layout, "control", "rotation_deg")
    bendy_scale = _ranges(layout, "bendy", "scale")
    for curve in layout["curves"]:
        for end in ("Start", "End"):
            bone = f"{curve}-{end}"
            specs += _vector_specs("location", bone, control_location, 0.0)
            specs += _vector_specs("rotation", bone, control_rotation, 0.0)
        specs.append(ParameterSpec(f"Scale_{curve}-Bendy", "scale", f"{curve}-Bendy", None, 1.0,
                                   *bendy_scale))
    for key, (lower, upper) in layout["shape_keys"].items():
        specs.append(ParameterSpec(f"Shape_key_{key}", "shape_key", key, None, 0.0, float(lower), float(upper),
                                   float(lower), float(upper)))
    return tuple(specs)


@lru_cache(maxsize=1)
def _index() -> dict[str, int]:
    return {spec.name: i for i, spec in enumerate(parameter_specs())}


def parameter_names() -> list[str]:
    """The 144 parameter names in canonical order."""
    return [spec.name for spec in parameter_specs()]


def _suggest(name: str) -> str:
    import difflib

    close = difflib.get_close_matches(name, parameter_names(), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


class PinnaParameters:
    """A full set of the 144 PPM parameters, stored as a float64 vector in canonical order.

    Instances are immutable; `with_values` returns a changed copy. Values are checked on
    construction: NaN/inf always raise; out-of-range values raise with `out_of_range='raise'`
    (the default) or are clamped to the bounds with `out_of_range='clip'`.
    """

    __slots__ = ("_values",)

    def __init__(self, values: Iterable[float] | None = None, *, out_of_range: str = "raise"):
        specs = parameter_specs()
        vector = (np.array([s.default for s in specs]) if values is None
                  else np.array(list(values) if not isinstance(values, np.ndarray) else values, dtype=np.float64))
        if vector.shape != (len(specs),):
            raise PpmError(f"a parameter vector needs {len(specs)} values, got shape {vector.shape}")
        self._values = _checked(vector, out_of_range)
        self._values.flags.writeable = False

    # construction -------------------------------------------------------------------------
    @classmethod
    def default(cls) -> "PinnaParameters":
        """The rest pose: zero locations and rotations, unit scales, zero shape-key weights."""
        return cls()

    @classmethod
    def from_vector(cls, vector: np.ndarray, *, out_of_range: str = "raise") -> "PinnaParameters":
        """From a (144,) vector in canonical order (see :func:`parameter_names`)."""
        return cls(np.asarray(vector, dtype=np.float64), out_of_range=out_of_range)

    @classmethod
    def from_dict(cls, named: Mapping[str, float], *, out_of_range: str = "raise") -> "PinnaParameters":
        """From a mapping name -> value; names not given keep their defaults; unknown names raise."""
        return cls.default().with_values(named, out_of_range=out_of_range)

    def with_values(self, named: Mapping[str, float], *, out_of_range: str = "raise") -> "PinnaParameters":
        """A copy with the named parameters changed."""
        index = _index()
        unknown = [name for name in named if name not in index]
        if unknown:
            raise PpmError("unknown PPM parameter name(s): "
                           + ", ".join(f"{name!r}{_suggest(name)}" for name in unknown))
        vector = self._values.copy()
        for name, value in named.items():
            try:
                vector[index[name]] = float(value)
            except (TypeError, ValueError) as exc:
                raise PpmError(f"parameter {name!r}: value {value!r} is not a number") from exc
        return PinnaParameters(vector, out_of_range=out_of_range)

    # access -------------------------------------------------------------------------------
    def to_vector(self) -> np.ndarray:
        """(144,) float64 copy in canonical order."""
        return self._values.copy()

    def to_dict(self) -> dict[str, float]:
        """Ordered mapping name -> value."""
        return {name: float(v) for name, v in zip(parameter_names(), self._values)}

    def __getitem__(self, name: str) -> float:
        index = _index()
        if name not in index:
            raise PpmError(f"unknown PPM parameter name {name!r}{_suggest(name)}")
        return float(self._values[index[name]])

    def __len__(self) -> int:
        return len(self._values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PinnaParameters) and np.array_equal(self._values, other._values)

    def __repr__(self) -> str:
        changed = {k: v for k, v, s in zip(parameter_names(), self._values, parameter_specs()) if v != s.default}
        return f"PinnaParameters({len(changed)} changed from default: {changed})"

    def deviation(self) -> dict[str, float]:
        """Value minus default for every parameter (mm, deg, factor or weight)."""
        return {s.name: float(v - s.default) for s, v in zip(parameter_specs(), self._values)}

    # I/O ----------------------------------------------------------------------------------
    def to_csv(self) -> str:
        """CSV text with columns name, value, unit, default, lower, upper."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(["name", "value", "unit", "default", "lower", "upper"])
        for spec, value in zip(parameter_specs(), self._values):
            writer.writerow([spec.name, repr(float(value)), spec.unit, spec.default, spec.lower, spec.upper])
        return buffer.getvalue()

    def to_json(self) -> str:
        """JSON text: {"units": ..., "parameters": {name: value}}."""
        payload = {
            "model": "parametric pinna model (PPM), left ear",
            "units": {"location": "mm", "rotation": "deg, Euler ZYX", "scale": "factor", "shape_key": "weight"},
            "parameters": self.to_dict(),
        }
        return json.dumps(payload, indent=2) + "\n"

    def write(self, path: str | os.PathLike) -> Path:
        """Write to `.csv` or `.json` (by suffix), atomically."""
        path = Path(path)
        if path.suffix.lower() == ".csv":
            return write_text_atomic(path, self.to_csv())
        if path.suffix.lower() == ".json":
            return write_text_atomic(path, self.to_json())
        raise PpmError(f"{path}: parameters are written as .csv or .json, not {path.suffix!r}")

    @classmethod
    def read(cls, path: str | os.PathLike, *, out_of_range: str = "raise") -> "PinnaParameters":
        """Read a `.csv` (columns name, value, ...) or `.json` file written by :meth:`write`."""
        path = Path(path)
        if not path.is_file():
            raise PpmError(f"{path}: no such parameter file")
        text = path.read_text(encoding="utf-8")
        if not text.strip():
            raise PpmError(f"{path}: the parameter file is empty")
        try:
            if path.suffix.lower() == ".csv":
                rows = list(csv.DictReader(io.StringIO(text)))
                if not rows or "name" not in rows[0] or "value" not in rows[0]:
                    raise PpmError(f"{path}: a parameter CSV needs the columns 'name' and 'value'")
                named = {row["name"]: row["value"] for row in rows}
            elif path.suffix.lower() == ".json":
                payload = json.loads(text)
                named = payload.get("parameters", payload) if isinstance(payload, dict) else None
                if not isinstance(named, dict):
                    raise PpmError(f"{path}: expected a JSON object of name: value")
            else:
                raise PpmError(f"{path}: parameters are read from .csv or .json, not {path.suffix!r}")
        except (json.JSONDecodeError, csv.Error) as exc:
            raise PpmError(f"{path}: corrupt parameter file ({exc})") from exc
        try:
            return cls.from_dict(named, out_of_range=out_of_range)
        except PpmError as exc:
            raise PpmError(f"{path}: {exc}") from exc


def bounds() -> tuple[np.ndarray, np.ndarray]:
    """(144,) lower and upper bounds in canonical order."""
    specs = parameter_specs()
    return np.array([s.lower for s in specs]), np.array([s.upper for s in specs])


def _checked(vector: np.ndarray, out_of_range: str) -> np.ndarray:
    if out_of_range not in ("raise", "clip"):
        raise PpmError(f"out_of_range must be 'raise' or 'clip', got {out_of_range!r}")
    specs = parameter_specs()
    bad = ~np.isfinite(vector)
    if bad.any():
        names = [specs[i].name for i in np.flatnonzero(bad)]
        raise PpmError(f"parameter(s) {names} are NaN or infinite")
    lower, upper = bounds()
    outside = (vector < lower) | (vector > upper)
    if outside.any():
        if out_of_range == "clip":
            return np.clip(vector, lower, upper)
        details = ", ".join(f"{specs[i].name}={vector[i]:g} {specs[i].unit} not in [{lower[i]:g}, {upper[i]:g}]"
                            for i in np.flatnonzero(outside))
        raise PpmError(f"parameter(s) out of range: {details}; pass out_of_range='clip' to clamp them")
    return vector.copy()


def typical_ranges() -> tuple[np.ndarray, np.ndarray]:
    """(144,) lower and upper ends of the typical spread between listeners, in canonical order."""
    specs = parameter_specs()
    return np.array([s.typical_lower for s in specs]), np.array([s.typical_upper for s in specs])


def random_parameters(rng: np.random.Generator, fraction: float = 1.0) -> PinnaParameters:
    """A random ear: parameters drawn uniformly within `fraction` of each typical range around the
    default (for synthetic scans, tests, demos)."""
    specs = parameter_specs()
    default = np.array([s.default for s in specs])
    lower, upper = typical_ranges()
    low = default + fraction * (lower - default)
    high = default + fraction * (upper - default)
    return PinnaParameters(rng.uniform(low, high))
