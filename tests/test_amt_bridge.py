"""baumgartner2014 in Python: stage properties, agreement with AMT 0.9.10, real HRTF sets, bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest
import sofar

from amt_bridge import AmtBridgeError, HrirSet, LocalisationModel, read_hrtf_set
from amt_bridge.angles import spherical_to_horizontal_polar
from amt_bridge.cli import main as b2014_main
from amt_bridge.dtf import hrtf_to_dtf
from amt_bridge.filterbank import band_levels_db, centre_frequencies, gammatone_coefficients
from amt_bridge.performance import ARI_POLAR_DEG, chance_performance, performance
from amt_bridge.stages import gradient_offset, positive_gradients, sensorimotor_mapping

from conftest import ROOT, SHARED_DATA

HRTF = SHARED_DATA / "hrtf"
AXD1, AXD2 = HRTF / "measured_axd_example1.sofa", HRTF / "measured_axd_example2.sofa"
REFERENCE = ROOT / "tests" / "references" / "b2014_amt_reference.npz"
AMT_PAIRS = {
    "axd2_heard_by_axd1": (AXD2, AXD1),
    "p039_simulated_self": (SHARED_DATA / "sonicom/P039/hrir_mesh2hrtf_48k.sofa",) * 2,
    "kemar44k_heard_by_irc1003": (HRTF / "measured_mit_kemar.sofa", HRTF / "measured_listen_irc1003.sofa"),
}


@pytest.fixture(scope="module")
def axd1() -> HrirSet:
    return read_hrtf_set(AXD1)


def test_centre_frequencies_are_amt_s():
    fc = centre_frequencies()
    assert fc.size == 28
    np.testing.assert_allclose(fc[[0, 1, 2, -2, -1]], [729.475, 838.703, 960.380, 15631.567, 17439.330], atol=1e-3)
    assert gradient_offset(fc) == 1
    assert gradient_offset(centre_frequencies(spacing_erb=0.5)) == 2  # half-ERB bands: two bands apart


def test_gammatone_has_0_db_at_its_centre_frequency():
    fs = 48000.0
    for fc in centre_frequencies()[[0, 10, 27]]:
        b0, a = gammatone_coefficients(fc, fs)
        z = np.exp(-1j * 2 * np.pi * fc / fs)  # the pole sits at -fc; the real part mirrors it to +fc
        pole = -a[1] / 4  # a = poly([p, p, p, p]); evaluate the factored form, not the expanded polynomial
        np.testing.assert_allclose(np.poly(np.full(4, pole)), a, atol=1e-14)
        gain = abs(b0 / (1 - pole / z) ** 4)
        assert gain == pytest.approx(1.0, abs=1e-9)
    # a long unit cosine at fc: 2 Re{...} gives an RMS of 1/sqrt(2), i.e. -3.01 dB
    t = np.arange(48000) / fs
    fc = centre_frequencies()[12]
    level = band_levels_db(np.cos(2 * np.pi * fc * t)[:, None], fs, np.array([fc]))[0, 0]
    assert level == pytest.approx(-3.0103, abs=0.02)


def test_gradients_cancel_a_level_offset_and_predictions_ignore_gain(axd1):
    levels = np.random.default_rng(1).normal(size=(28, 5, 2))
    np.testing.assert_allclose(positive_gradients(levels + 7.5, 1), positive_gradients(levels, 1), atol=1e-12)
    dtf = hrtf_to_dtf(axd1)
    louder = HrirSet(dtf.irs * 10.0, dtf.sampling_rate_hz, dtf.azimuth_deg, dtf.elevation_deg)
    quiet = LocalisationModel(dtf, dtf, [0.0], already_dtf=True).predict()
    loud = LocalisationModel(louder, dtf, [0.0], already_dtf=True).predict()
    np.testing.assert_allclose(loud.planes[0].p, quiet.planes[0].p, atol=1e-9)


def test_probability_mass_vectors_sum_to_one_and_mapping_keeps_the_grid(axd1):
    prediction = LocalisationModel(axd1, axd1).predict()
    for plane in prediction.planes:
        np.testing.assert_allclose(plane.p.sum(axis=0), 1.0, atol=1e-12)
        assert (plane.p >= 0).all()
        np.testing.assert_array_equal(plane.rang, np.arange(-90.0, 270.0, 5.0))  # 72 responses, -90..265
    # a template ending at 209.9999999 drops the 210 response angle (MATLAB colon), as AMT does
    _, angles = sensorimotor_mapping(np.eye(5), np.array([-30, 30, 90, 150, 209.9999999]), 0.0, scatter_deg=0)
    assert angles[-1] == 205.0 and angles[0] == -30.0


def test_chance_performance_matches_amt():
    # pmv2ppp(ones(49,44)): AMT's calibration normalisers (Octave: 42.764378 %, 46.961551 deg)
    uniform_49 = performance(np.ones((49, 44)), ARI_POLAR_DEG, np.zeros(49))
    assert uniform_49.qe_percent == pytest.approx(42.764378, abs=1e-6)
    assert uniform_49.pe_deg == pytest.approx(46.961551, abs=1e-6)
    chance = chance_performance()
    assert chance.qe_percent == pytest.approx(51.388889, abs=1e-6)
    assert chance.pe_deg == pytest.approx(50.497525, abs=1e-6)


def test_polar_angles_carry_matlab_round_off():
    """MIT KEMAR's azimuth 180°, elevation 40° becomes 140.00000000000003 in AMT (spec pitfall 1)."""
    lateral, polar = spherical_to_horizontal_polar(np.array([180.0, 90.0, 0.0]), np.array([40.0, 0.0, -30.0]))
    assert polar[0] == 140.00000000000003
    assert lateral[1] == pytest.approx(90.0) and polar[2] == pytest.approx(-30.0)


@pytest.mark.parametrize("pair", sorted(AMT_PAIRS))
def test_agrees_with_amt(pair):
    """Same DTFs in, AMT 0.9.10 in Octave vs amt_bridge: p to 1e-6, QE/PE to 0.01 (reference made by
    benchmarks/amt_agreement.py --write-reference; rerun it with --amt/--ltfat to check live)."""
    reference = np.load(REFERENCE)
    target, template = (hrtf_to_dtf(read_hrtf_set(path)) for path in AMT_PAIRS[pair])
    prediction = LocalisationModel(target, template, [-20.0, 0.0, 20.0], already_dtf=True).predict(0.7)
    for k, plane in enumerate(prediction.planes, start=1):
        np.testing.assert_array_equal(plane.tang, reference[f"{pair}/tang{k}"].ravel())
        np.testing.assert_array_equal(plane.rang, reference[f"{pair}/rang{k}"].ravel())
        np.testing.assert_allclose(plane.p, reference[f"{pair}/p{k}"], atol=1e-6, rtol=0)
        assert plane.performance.qe_percent == pytest.approx(float(reference[f"{pair}/qe{k}"]), abs=0.01)
        assert plane.performance.pe_deg == pytest.approx(float(reference[f"{pair}/pe{k}"]), abs=0.01)
        assert plane.performance.eb_deg == pytest.approx(float(reference[f"{pair}/eb{k}"]), abs=0.01)


def test_self_prediction_is_low_and_another_listener_raises_errors(axd1):
    self_model = LocalisationModel(axd1, axd1)
    sensitivity = self_model.calibrate(8.0)
    assert 0.3 < sensitivity < 1.2
    assert self_model.predict(sensitivity).qe == pytest.approx(8.0, abs=0.01)
    for other in (AXD2, HRTF / "measured_mit_kemar.sofa", SHARED_DATA / "sonicom/P039/hrir_mesh2hrtf_48k.sofa"):
        foreign = LocalisationModel(read_hrtf_set(other), axd1).predict(sensitivity)
        assert foreign.qe > 15.0, other.name
        assert foreign.pe > self_model.predict(sensitivity).pe + 4.0, other.name


def test_an_unreachable_calibration_goal_is_an_error_or_the_closest_end_of_the_bracket(axd1):
    """No S in [0.05, 3] dB gives 60 % QE (chance is about 43-51 %): an error naming the QE range, or,
    as the workflow asks, the bracket end nearest the goal; the summary then says so."""
    from amt_bridge.evaluation import compare_conditions, comparison_summary  # noqa: PLC0415

    self_model = LocalisationModel(axd1, axd1)
    with pytest.raises(AmtBridgeError, match=r"no sensitivity in \[0.05, 3.0\] dB gives 60.0% .*QE runs from"):
        self_model.calibrate(60.0)
    assert self_model.calibrate(60.0, closest=True) == 3.0
    assert self_model.calibrate(0.001, closest=True) == 0.05
    sensitivity, predictions = compare_conditions(AXD1, {"other": AXD2}, 60.0, [0.0])
    summary = comparison_summary(AXD1, 60.0, sensitivity, predictions)
    assert sensitivity == 3.0 and not summary["calibration_reached"]
    assert f"{predictions['reference'].qe:.2f} %" in summary["calibration_note"]
    reached = comparison_summary(AXD1, 8.0, *compare_conditions(AXD1, {"other": AXD2}, 8.0, [0.0]))
    assert reached["calibration_reached"] and "calibration_note" not in reached


def test_simulated_hrtf_sofa_input_gives_the_same_prediction_as_its_hrirs(axd1, tmp_path):
    """A SimpleFreeFieldHRTF file (one-sided spectra) is turned into impulse responses first."""
    sofa = sofar.Sofa("SimpleFreeFieldHRTF")
    spectra = np.fft.rfft(axd1.irs, axis=-1)
    sofa.Data_Real, sofa.Data_Imag = spectra.real, spectra.imag
    sofa.N = np.fft.rfftfreq(axd1.irs.shape[-1], 1 / axd1.sampling_rate_hz)
    sofa.SourcePosition = np.c_[axd1.azimuth_deg, axd1.elevation_deg, np.full(axd1.azimuth_deg.size, 1.5)]
    sofa.ReceiverPosition = [[0, 0.09, 0], [0, -0.09, 0]]
    sofar.write_sofa(str(tmp_path / "hrtf.sofa"), sofa)
    as_hrtf = read_hrtf_set(tmp_path / "hrtf.sofa")
    assert as_hrtf.sampling_rate_hz == axd1.sampling_rate_hz and as_hrtf.irs.shape == axd1.irs.shape
    reference = LocalisationModel(axd1, axd1).predict(0.7)
    converted = LocalisationModel(as_hrtf, axd1).predict(0.7)
    assert abs(converted.qe - reference.qe) < 1.0 and abs(converted.pe - reference.pe) < 1.0


def _write_hrir_sofa(path, irs, fs=48000.0, azimuth=None, elevation=None):
    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    sofa.Data_IR = irs
    sofa.Data_SamplingRate = fs
    m = irs.shape[0]
    azimuth = np.linspace(0, 350, m) if azimuth is None else azimuth
    elevation = np.zeros(m) if elevation is None else elevation
    sofa.SourcePosition = np.c_[azimuth, elevation, np.ones(m)]
    sofa.ReceiverPosition = np.zeros((irs.shape[1], 3))
    sofa.Data_Delay = np.zeros((1, irs.shape[1]))
    sofar.write_sofa(str(path), sofa)
    return path


def test_bad_input_is_named(tmp_path, axd1):
    with pytest.raises(AmtBridgeError, match="2 ears"):
        read_hrtf_set(_write_hrir_sofa(tmp_path / "mono.sofa", axd1.irs[:, :1, :]))
    with pytest.raises(AmtBridgeError, match="NaN"):
        irs = axd1.irs.copy()
        irs[3, 0, 10] = np.nan
        HrirSet(irs, 48000.0, axd1.azimuth_deg, axd1.elevation_deg)
    (tmp_path / "empty.sofa").write_bytes(b"")
    with pytest.raises(AmtBridgeError, match="empty"):
        read_hrtf_set(tmp_path / "empty.sofa")
    (tmp_path / "notes.sofa").write_text("not a SOFA file\n")
    with pytest.raises(AmtBridgeError, match="not a readable SOFA file"):
        read_hrtf_set(tmp_path / "notes.sofa")
    low_rate = HrirSet(axd1.irs, 32000.0, axd1.azimuth_deg, axd1.elevation_deg)
    with pytest.raises(AmtBridgeError, match="sampling rate 32000 Hz is too low"):
        LocalisationModel(low_rate, axd1, [0.0])
    horizontal = HrirSet(axd1.irs[:36], 48000.0, np.arange(0, 360, 10.0), np.zeros(36))
    with pytest.raises(AmtBridgeError, match="lateral angle 0 deg"):  # only front and back lie in the median plane
        LocalisationModel(horizontal, horizontal, [0.0])


def test_mixed_sampling_rates_are_analysed_each_at_its_own_rate(axd1):
    kemar = read_hrtf_set(HRTF / "measured_mit_kemar.sofa")
    assert kemar.sampling_rate_hz == 44100.0
    prediction = LocalisationModel(kemar, axd1).predict()
    assert np.isfinite([prediction.qe, prediction.pe, prediction.eb]).all()


def test_cli_compare_writes_json_and_figures(tmp_path):
    code = b2014_main(["compare", str(AXD1), f"axd2={AXD2}", "--bars", str(tmp_path / "bars.png"),
                       "--matrix-dir", str(tmp_path / "matrices"), "--json", str(tmp_path / "result.json")])
    assert code == 0
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["conditions"]["reference"]["qe_percent"] == pytest.approx(8.0, abs=0.01)
    assert result["conditions"]["axd2"]["qe_percent"] > 15
    assert (tmp_path / "bars.png").stat().st_size > 1000
    assert sorted(p.name for p in (tmp_path / "matrices").iterdir()) == ["axd2_matrix.png", "reference_matrix.png"]
    assert b2014_main(["predict", str(tmp_path / "missing.sofa"), str(AXD1)]) == 2


def test_experimental_targets_interpolate_per_target_values(axd1):
    plane = LocalisationModel(axd1, axd1, [0.0]).predict().planes[0]
    same = performance(plane.p, plane.tang, plane.rang, experimental_polar_deg=plane.tang)
    assert same.qe_percent == pytest.approx(plane.performance.qe_percent, abs=1e-9)
    assert same.pe_deg == pytest.approx(plane.performance.pe_deg, abs=1e-9)
    # a target counted twice weighs twice; a target halfway between two gets their mean
    doubled = performance(plane.p, plane.tang, plane.rang, experimental_polar_deg=[plane.tang[0]] * 2 + [plane.tang[1]])
    expected = (2 * plane.performance.qe_per_target[0] + plane.performance.qe_per_target[1]) / 3 * 100
    assert doubled.qe_percent == pytest.approx(expected, abs=1e-9)
    middle = performance(plane.p, plane.tang, plane.rang, experimental_polar_deg=[(plane.tang[2] + plane.tang[3]) / 2])
    assert middle.pe_deg == pytest.approx(plane.performance.pe_per_target[2:4].mean(), abs=1e-9)


def test_a_one_ear_set_takes_the_other_ear_from_the_reference_direction_by_direction(tmp_path, sonicom):
    """The evaluation solves the left ear only; the right ear comes from the reference, matched by direction
    (the solved file's directions in another order), so that only the left pinna differs."""
    from amt_bridge.evaluation import compare_conditions
    from amt_bridge.hrtf_set import read_one_ear_completed

    reference_path = sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa"
    reference = read_hrtf_set(reference_path)
    order = np.random.default_rng(3).permutation(len(reference.azimuth_deg))
    left_only = _write_hrir_sofa(tmp_path / "left.sofa", reference.irs[order, :1, :],
                                 azimuth=reference.azimuth_deg[order], elevation=reference.elevation_deg[order])
    completed = read_one_ear_completed(left_only, "left", reference)
    assert np.array_equal(completed.irs, reference.irs[order])
    # the reference's own left ear, completed, is predicted as the reference itself (order does not matter)
    sensitivity, predictions = compare_conditions(reference_path, {"own_left": left_only}, solved_ear="left")
    assert predictions["reference"].qe == pytest.approx(8.0, abs=0.01)
    assert predictions["own_left"].qe == pytest.approx(predictions["reference"].qe, abs=1e-4)
    assert predictions["own_left"].pe == pytest.approx(predictions["reference"].pe, abs=1e-4)
    # the left ear of another listener (P067) moves the prediction
    other = read_hrtf_set(sonicom / "P067" / "hrir_mesh2hrtf_48k.sofa")
    foreign = _write_hrir_sofa(tmp_path / "foreign.sofa", other.irs[:, :1, :], azimuth=other.azimuth_deg,
                               elevation=other.elevation_deg)
    _, moved = compare_conditions(reference_path, {"foreign_left": foreign}, solved_ear="left")
    assert moved["foreign_left"].qe > predictions["reference"].qe + 1.0

    elsewhere = _write_hrir_sofa(tmp_path / "moved.sofa", reference.irs[:, :1, :],
                                 azimuth=reference.azimuth_deg + 2.0, elevation=reference.elevation_deg)
    with pytest.raises(AmtBridgeError, match="do not match"):
        read_one_ear_completed(elsewhere, "left", reference)
    with pytest.raises(AmtBridgeError, match="one-ear file"):
        read_one_ear_completed(reference_path, "left", reference)
    short = _write_hrir_sofa(tmp_path / "short.sofa", reference.irs[:, :1, :128],
                             azimuth=reference.azimuth_deg, elevation=reference.elevation_deg)
    with pytest.raises(AmtBridgeError, match="rebuild both alike"):
        read_one_ear_completed(short, "left", reference)


def test_directional_levels_drop_a_per_frequency_gain_and_keep_what_differs_between_directions():
    from amt_bridge.dtf import directional_levels_db

    rng = np.random.default_rng(3)
    spectra = rng.normal(size=(50, 7)) + 1j * rng.normal(size=(50, 7))
    gained = spectra * (10.0 ** (rng.normal(size=7) / 20.0)) * np.exp(1j * rng.normal(size=7))
    np.testing.assert_allclose(directional_levels_db(gained), directional_levels_db(spectra), atol=1e-9)
    louder_first = spectra.copy()
    louder_first[0] *= 2.0  # +6.02 dB in one direction moves it by 6.02 * (1 - 1/50) against the mean
    np.testing.assert_allclose(directional_levels_db(louder_first)[0] - directional_levels_db(spectra)[0],
                               20 * np.log10(2.0) * (1 - 1 / 50), atol=1e-9)


def test_sets_on_different_grids_are_compared_on_the_directions_they_share(sonicom):
    """A denser set (SONICOM P143's directions below 60 deg elevation turned by 1 deg in azimuth, plus every
    direction again 2.5 deg up and 2.5 deg round, with other responses) shares every one of the coarse set's directions within 2 deg: its nearest responses take the coarse set's
    directions, and the model on the shared grid gives the coarse set's own QE heard through itself."""
    import dataclasses

    from amt_bridge.hrtf_set import on_common_directions

    coarse = read_hrtf_set(sonicom / "P143" / "hrir_mesh2hrtf_48k.sofa")
    away_from_poles = np.abs(coarse.elevation_deg) < 60.0  # at a pole every azimuth is one direction
    coarse = dataclasses.replace(coarse, irs=coarse.irs[away_from_poles], azimuth_deg=coarse.azimuth_deg[away_from_poles],
                                 elevation_deg=coarse.elevation_deg[away_from_poles])
    dense = dataclasses.replace(coarse, irs=np.concatenate([coarse.irs, coarse.irs[::-1]]),
                                azimuth_deg=np.r_[coarse.azimuth_deg + 1.0, coarse.azimuth_deg + 2.5],
                                elevation_deg=np.r_[coarse.elevation_deg, coarse.elevation_deg + 2.5])
    first, second = on_common_directions(dense, coarse)
    assert first.irs.shape == coarse.irs.shape
    np.testing.assert_array_equal(first.irs, coarse.irs)  # the 1-deg neighbours, not the others
    np.testing.assert_array_equal(first.azimuth_deg, second.azimuth_deg)
    model = LocalisationModel(coarse, coarse, [0.0])
    sensitivity = model.calibrate(8.0)
    assert LocalisationModel(first, second, [0.0]).predict(sensitivity).qe == pytest.approx(8.0, abs=0.05)
    with pytest.raises(AmtBridgeError, match="share only"):
        on_common_directions(dataclasses.replace(coarse, azimuth_deg=coarse.azimuth_deg + 1.0), coarse, 0.1)
