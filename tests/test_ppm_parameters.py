"""The 144 named PPM parameters: counts, names, bounds, conversions, I/O and bad input."""
import json

import numpy as np
import pytest

from ppm.errors import PpmError
from ppm.parameters import (PinnaParameters, bounds, parameter_names, parameter_specs, random_parameters,
                            typical_ranges)


def test_exactly_144_parameters_in_the_spec_groups():
    specs = parameter_specs()
    assert len(specs) == 144
    assert len(set(parameter_names())) == 144
    kinds = [s.kind for s in specs]
    assert kinds.count("shape_key") == 18
    # parent 3+3+3, 18 control bones x 6, 9 bendy scales
    assert kinds.count("location") == 3 + 18 * 3
    assert kinds.count("rotation") == 3 + 18 * 3
    assert kinds.count("scale") == 3 + 9


def test_names_follow_the_spec():
    names = set(parameter_names())
    for name in ("Location_Size-Bendy_X", "Rotation_Size-Bendy_Y", "Scale_Size-Bendy_Z", "Scale_Lobulus-Bendy",
                 "Location_Tragus-Start_X", "Rotation_Helix_up-End_Z", "Shape_key_Cavum_conchae-Depth",
                 "Shape_key_Ear_canal-Diameter", "Location_Crus_superius_anthelicis-End_Y"):
        assert name in names


def test_shape_key_ranges_are_the_spec_table():
    p = {s.name: (s.lower, s.upper) for s in parameter_specs()}
    assert p["Shape_key_Cymba_conchae-Depth"] == (0.0, 1.0)
    assert p["Shape_key_Cavum_conchae-Depth"] == (-1.0, 1.0)
    assert p["Shape_key_Tragus-Upper_dent"] == (-1.0, 1.0)
    assert p["Shape_key_Lobulus-Form"] == (0.0, 1.0)


def test_defaults_and_vector_round_trip(rng):
    default = PinnaParameters.default()
    assert default["Scale_Size-Bendy_X"] == 1.0 and default["Location_Tragus-Start_X"] == 0.0
    params = random_parameters(rng)
    again = PinnaParameters.from_vector(params.to_vector())
    assert again == params
    assert PinnaParameters.from_dict(params.to_dict()) == params


def test_random_ears_are_drawn_from_the_typical_spread_inside_the_bounds(rng):
    lower, upper = bounds()
    typical_lower, typical_upper = typical_ranges()
    assert (lower <= typical_lower).all() and (typical_upper <= upper).all()
    name = parameter_names().index("Location_Tragus-Start_X")
    assert (typical_lower[name], typical_upper[name]) == (-2.0, 2.0) and (lower[name], upper[name]) == (-6.0, 6.0)
    drawn = np.array([random_parameters(rng, 0.5).to_vector() for _ in range(200)])
    default = np.array([s.default for s in parameter_specs()])
    assert (drawn >= default + 0.5 * (typical_lower - default) - 1e-12).all()
    assert (drawn <= default + 0.5 * (typical_upper - default) + 1e-12).all()
    assert np.abs(drawn[:, name]).max() > 0.9  # spans the half range, not a point


def test_csv_and_json_round_trip(tmp_path, rng):
    params = random_parameters(rng)
    for suffix in (".csv", ".json"):
        path = params.write(tmp_path / f"p{suffix}")
        assert PinnaParameters.read(path) == params  # repr() of floats round-trips exactly
    payload = json.loads((tmp_path / "p.json").read_text())
    assert payload["parameters"]["Scale_Size-Bendy_Y"] == params["Scale_Size-Bendy_Y"]


def test_unknown_name_is_named_with_a_suggestion():
    with pytest.raises(PpmError, match=r"unknown PPM parameter name.*'Location_Tragus-Strat_X'.*did you mean"):
        PinnaParameters.from_dict({"Location_Tragus-Strat_X": 1.0})


def test_out_of_range_raises_or_clips():
    with pytest.raises(PpmError, match=r"Shape_key_Cymba_conchae-Depth=-0.5 weight not in \[0, 1\]"):
        PinnaParameters.from_dict({"Shape_key_Cymba_conchae-Depth": -0.5})
    clipped = PinnaParameters.from_dict({"Shape_key_Cymba_conchae-Depth": -0.5, "Rotation_Tragus-End_X": 400},
                                        out_of_range="clip")
    lower, upper = bounds()
    assert clipped["Shape_key_Cymba_conchae-Depth"] == 0.0
    assert clipped["Rotation_Tragus-End_X"] == upper[parameter_names().index("Rotation_Tragus-End_X")]


def test_nan_is_refused():
    with pytest.raises(PpmError, match=r"Scale_Lobulus-Bendy.*NaN"):
        PinnaParameters.from_dict({"Scale_Lobulus-Bendy": float("nan")})
    vector = PinnaParameters.default().to_vector()
    vector[5] = np.inf
    with pytest.raises(PpmError, match="NaN or infinite"):
        PinnaParameters.from_vector(vector)


def test_wrong_length_and_bad_files(tmp_path):
    with pytest.raises(PpmError, match="needs 144 values"):
        PinnaParameters.from_vector(np.zeros(143))
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(PpmError, match="empty"):
        PinnaParameters.read(empty)
    corrupt = tmp_path / "bad.json"
    corrupt.write_text("{not json")
    with pytest.raises(PpmError, match="corrupt parameter file"):
        PinnaParameters.read(corrupt)
    with pytest.raises(PpmError, match="no such parameter file"):
        PinnaParameters.read(tmp_path / "missing.csv")
    with pytest.raises(PpmError, match="not a number"):
        PinnaParameters.from_dict({"Scale_Lobulus-Bendy": "big"})
