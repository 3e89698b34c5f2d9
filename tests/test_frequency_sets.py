"""Frequency sets and HRIRs rebuilt from a sparse set: exact where the data are complete, within 0.1 dB
on a smooth response, like with like on a real SONICOM set, clear errors for bad sets."""
from __future__ import annotations

import json

import numpy as np
import pytest
import sofar
import trimesh

from amt_bridge import read_hrtf_set
from amt_bridge.hrtf_set import resampled_at
from amt_bridge.model import LocalisationModel
from mesh2hrtf_io import Mesh2HrtfIoError, sphere_grid, write_project
from mesh2hrtf_io.constants import HRIR_LEAD_S
from mesh2hrtf_io.frequency_sets import (check_frequency_set, describe_set, frequencies_from_spec, is_linear_grid,
                                         presets)
from mesh2hrtf_io.project_reader import read_project
from mesh2hrtf_io.results import write_eval_grid_pressure
from mesh2hrtf_io.sofa_out import collect_sofa
from mesh2hrtf_io.sparse_hrtf import low_frequency_delay, rebuild_hrirs
from mesh2hrtf_io.ear_canal import ear_canal_elements

RATE = 48000.0
N = 320
GRID = np.arange(N // 2 + 1) * RATE / N
EVALUATION = frequencies_from_spec({"preset": "evaluation"})


def _minimum_phase_fir(rng, n_zeros=12) -> np.ndarray:
    """A minimum-phase FIR: real and complex-conjugate zeros inside the unit circle."""
    radius = rng.uniform(0.3, 0.8, n_zeros // 2)
    angle = rng.uniform(0.1, 3.0, n_zeros // 2)
    zeros = np.concatenate([radius * np.exp(1j * angle), radius * np.exp(-1j * angle)])
    h = np.poly(zeros).real
    return h / h.sum()


def test_the_evaluation_preset_is_40_frequencies_to_24_khz():
    assert EVALUATION.size == 40 and EVALUATION[0] == 150.0 and EVALUATION[-1] == 24000.0
    assert (np.diff(EVALUATION) > 0).all() and not is_linear_grid(EVALUATION)
    # denser than 0.85-ERB steps at high frequencies: 6 kHz-warped steps are ~900 Hz at 16 kHz
    step_16k = np.diff(EVALUATION)[np.searchsorted(EVALUATION, 16000.0) - 1]
    assert 800 < step_16k < 1000
    assert "40 frequencies, 150 Hz to 24000 Hz, sparse set" in describe_set(EVALUATION)
    assert is_linear_grid(frequencies_from_spec({"preset": "sonicom_linear"}))
    np.testing.assert_array_equal(frequencies_from_spec("evaluation"), EVALUATION)  # a name is a preset
    assert set(presets()) >= {"evaluation", "erb_half", "sonicom_linear"}


def test_every_form_of_a_set_is_read():
    np.testing.assert_allclose(frequencies_from_spec({"min": 100.0, "max": 500.0, "step": 100.0}),
                               [100, 200, 300, 400, 500])
    np.testing.assert_allclose(frequencies_from_spec({"list": [300.0, 1000.5, 7000.25]}), [300, 1000.5, 7000.25])
    erb = frequencies_from_spec({"scale": "erb", "min": 1000.0, "max": 4000.0, "step_erb": 1.0, "extra": [200.0]})
    assert erb[0] == 200.0 and erb[1] == 1000.0
    erb_number = 9.2645 * np.log1p(0.00437 * erb[1:])
    np.testing.assert_allclose(np.diff(erb_number), 1.0, atol=1e-3)
    warped = frequencies_from_spec({"scale": "warped", "min": 500.0, "max": 20000.0, "count": 5, "corner_hz": 6000.0})
    np.testing.assert_allclose(np.diff(np.log1p(warped / 6000.0)), np.log1p(20000 / 6000) / 4 - np.log1p(500 / 6000) / 4,
                               atol=1e-5)


@pytest.mark.parametrize("spec, message", [
    ({"preset": "nonesuch"}, "unknown preset 'nonesuch'; known: .*evaluation"),
    ({"list": [100.0, 300.0, 200.0]}, "sorted in increasing order"),
    ({"list": [100.0, 200.0, 200.0]}, r"duplicate frequencies \[200.0\]"),
    ({"list": [0.0, 200.0]}, "above 0 Hz"),
    ({"list": [100.0, float("nan")]}, "finite"),
    ({"scale": "erb", "min": 600.0, "max": 18000.0}, r"needs the keys \['step_erb'\]"),
    ({"scale": "mel", "min": 600.0, "max": 18000.0}, "scale must be one of"),
    ({"scale": "erb", "min": 600.0, "max": 18000.0, "step_erb": 1.0, "extra": [1000.0]}, "outside"),
    ({"fmin": 100}, "cannot read"),
])
def test_bad_sets_are_refused_with_the_reason(spec, message):
    with pytest.raises(Mesh2HrtfIoError, match=message):
        frequencies_from_spec(spec, "test set")


def test_bad_sets_for_a_rebuild_are_refused():
    spectra = np.ones((2, 10), complex)
    good = np.linspace(200.0, 20000.0, 10)
    with pytest.raises(Mesh2HrtfIoError, match="above the Nyquist frequency 12000 Hz"):
        rebuild_hrirs(spectra, good, 24000.0, 256)
    with pytest.raises(Mesh2HrtfIoError, match="7 frequencies are too few; rebuilding HRIRs needs at least 8"):
        rebuild_hrirs(spectra[:, :7], good[:7], RATE, N)
    with pytest.raises(Mesh2HrtfIoError, match="sorted"):
        rebuild_hrirs(spectra, good[::-1], RATE, N)
    with pytest.raises(Mesh2HrtfIoError, match="duplicate"):
        rebuild_hrirs(spectra, np.r_[good[:5], good[4:9]], RATE, N)
    with pytest.raises(Mesh2HrtfIoError, match="9 spectral values per response for 10 frequencies"):
        rebuild_hrirs(spectra[:, :9], good, RATE, N)
    with pytest.raises(Mesh2HrtfIoError, match="NaN"):
        rebuild_hrirs(np.full((2, 10), np.nan + 0j), good, RATE, N)
    assert check_frequency_set([100.0, 200.0], "x").tolist() == [100.0, 200.0]


def test_rebuild_is_exact_for_a_minimum_phase_filter_on_the_full_grid(rng):
    """Given on every bin (0 Hz included), magnitude interpolation is the identity and a minimum-phase
    filter has no excess delay: the rebuild returns the filter itself."""
    filters = np.stack([_minimum_phase_fir(rng) for _ in range(4)])
    spectra = np.fft.rfft(filters, n=N, axis=-1)
    rebuilt = rebuild_hrirs(spectra, GRID, RATE, N)
    padded = np.zeros_like(rebuilt)
    padded[:, : filters.shape[1]] = filters
    np.testing.assert_allclose(rebuilt, padded, atol=1e-9)


def test_a_smooth_delayed_response_rebuilds_within_0_1_db_from_the_evaluation_set():
    """A resonance at 4 kHz (3 kHz wide) and a dip at 12 kHz (8 kHz wide), delayed by 0.4 ms: its levels on
    the 150 Hz grid within 0.1 dB, its delay within 1 sample. (A dip narrower than a few set steps comes out
    shallower: PCHIP does not overshoot its samples; 5 kHz wide, the dip loses 0.13 dB.)"""
    def response(f):
        s = 1j * f
        resonance = 1 + 0.8 * (s * 3000) / (4000**2 - f**2 + s * 3000)
        dip = 1 - 0.5 * (s * 8000) / (12000**2 - f**2 + s * 8000)
        return resonance * dip * np.exp(-2j * np.pi * f * 0.4e-3)

    rebuilt = rebuild_hrirs(response(EVALUATION)[None], EVALUATION, RATE, N)[0]
    levels = 20 * np.log10(np.abs(np.fft.rfft(rebuilt)))
    truth = 20 * np.log10(np.abs(response(GRID)))
    assert np.abs(levels - truth).max() < 0.1
    delay_true = low_frequency_delay(response(EVALUATION)[None], EVALUATION)[0]
    delay_rebuilt = low_frequency_delay(np.fft.rfft(rebuilt)[None, 1:], GRID[1:])[0]
    assert abs(delay_rebuilt - delay_true) * RATE < 1.0


def test_above_the_highest_solved_frequency_the_level_fades_to_nyquist():
    f = np.linspace(300.0, 12000.0, 20)
    rebuilt = rebuild_hrirs(np.ones((1, f.size), complex), f, RATE, N)[0]
    levels = 20 * np.log10(np.abs(np.fft.rfft(rebuilt)) + 1e-12)
    assert np.abs(levels[GRID <= 12000]).max() < 0.01
    middle = np.argmin(np.abs(GRID - 18000))
    assert levels[middle] == pytest.approx(20 * np.log10(np.cos(np.pi / 4)), abs=0.05)  # half way: cos(45°)
    assert levels[-1] < -80


def test_a_real_set_rebuilt_from_the_evaluation_set_predicts_like_the_full_set(sonicom):
    """P039's reference HRIRs sampled at the 40 frequencies and rebuilt: PE of self-prediction (S calibrated
    on each) within 0.5°, levels within a few dB, and the interaural delay of lateral sources kept."""
    full = read_hrtf_set(sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa")
    rebuilt = resampled_at(full, EVALUATION)
    assert rebuilt.irs.shape == full.irs.shape and rebuilt.sampling_rate_hz == full.sampling_rate_hz
    predictions = []
    for hrirs in (full, rebuilt):
        model = LocalisationModel(hrirs, hrirs)
        predictions.append(model.predict(model.calibrate(8.0)))
    assert abs(predictions[0].pe - predictions[1].pe) < 0.5
    left = int(np.argmin(np.abs(full.azimuth_deg - 90) + np.abs(full.elevation_deg)))
    onsets = [np.argmax(np.abs(h.irs[left]) > 0.3 * np.abs(h.irs[left]).max(axis=-1, keepdims=True), axis=-1)
              for h in (full, rebuilt)]
    itd = [int(o[1] - o[0]) for o in onsets]
    assert itd[0] > 20 and abs(itd[1] - itd[0]) <= 2  # ~0.6 ms at 48 kHz, kept within 2 samples


def test_a_sparse_project_collects_to_verified_sofa_with_rebuilt_hrirs(tmp_path):
    """Export with the 40-frequency set (NC.inp's frequency curve holds the list), results standing in for
    a solver (a pure delay of each ear's travel time), collection: HRTFs at the 40 frequencies, HRIRs at
    48 kHz, 320 taps, each saying how it was made."""
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=87.5)
    ears = {side: ear_canal_elements(mesh, side) for side in ("left", "right")}
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=1, radius=1.2).vertices)
    write_project(tmp_path / "p", mesh.vertices, mesh.faces, ears, [grid], EVALUATION, speed_of_sound_m_s=343.0,
                  density_kg_m3=1.2, compute_hrirs=True)
    curve = (tmp_path / "p" / "NumCalc" / "source_1" / "NC.inp").read_text().split("## Load Frequency Curve\n")[1]
    lines = curve.split("\n")
    assert lines[0] == "0 41"
    written = np.array([float(line.split(" ")[1]) for line in lines[2:42]])
    np.testing.assert_allclose(written, EVALUATION, atol=0.005)
    project = read_project(tmp_path / "p")
    np.testing.assert_allclose(project.frequencies_hz, EVALUATION)
    assert json.loads((tmp_path / "p" / "parameters.json").read_text())["frequencyStepSize"] == 0.0
    from mesh2hrtf_io.bem import free_field_reference

    delays = {}
    for source, side in zip(project.sources, ("left", "right")):
        area = mesh.area_faces[ears[side]].sum() / 1e6
        ear_y = 0.0875 if side == "left" else -0.0875
        delays[side] = -grid.points_m[:, 1] / 1.2 * ear_y / 343.0  # far-field lead of the nearer ear (s)
        for step, f in enumerate(EVALUATION, start=1):
            hrtf = np.exp(-2j * np.pi * f * delays[side])  # DFT convention
            write_eval_grid_pressure(source.folder, step, project.grids[0].node_ids,
                                     np.conj(hrtf) * free_field_reference(grid.points_m, f, area, 343.0, 1.2))
    files = collect_sofa(tmp_path / "p")
    hrtf = sofar.read_sofa(str(files[0]), verify=True)
    np.testing.assert_allclose(hrtf.N, EVALUATION)
    assert "solved at 40 frequencies" in hrtf.GLOBAL_Comment
    hrir = sofar.read_sofa(str(files[1]), verify=True)
    assert hrir.Data_SamplingRate == RATE and hrir.Data_IR.shape == (len(grid.points_m), 2, N)
    assert "rebuilt from 40 frequencies" in hrir.GLOBAL_Comment and "PCHIP" in hrir.GLOBAL_Comment
    peaks = np.argmax(np.abs(hrir.Data_IR), axis=-1) / RATE
    expected = np.stack([delays["left"], delays["right"]], axis=-1) + HRIR_LEAD_S
    assert np.abs(peaks - expected).max() < 2.5 / RATE
    as_read = read_hrtf_set(files[0])  # b2014 reads a sparse HRTF file by the same rebuild: the very HRIRs
    assert as_read.sampling_rate_hz == RATE and as_read.irs.shape[-1] == N
    np.testing.assert_allclose(as_read.irs, hrir.Data_IR, rtol=0, atol=1e-12 * np.abs(hrir.Data_IR).max())


def test_cli_exports_a_preset_and_the_cost_counts_its_steps(tmp_path, capsys):
    from mesh2hrtf_io.cli import main as m2h_main

    head = tmp_path / "head.ply"
    trimesh.creation.icosphere(subdivisions=2, radius=87.5).export(head)
    assert m2h_main(["export", str(head), str(tmp_path / "p"), "--preset", "evaluation", "--ears", "left"]) == 0
    assert json.loads(capsys.readouterr().out)["frequencies"] == 40
    assert m2h_main(["cost", str(tmp_path / "p"), "--solver", "numcalc"]) == 0
    cost = json.loads(capsys.readouterr().out)
    assert cost["n_frequencies"] == 40 and cost["n_sources"] == 1
    assert m2h_main(["export", str(head), str(tmp_path / "q"), "--frequencies", "500", "400"]) == 2
    assert "sorted in increasing order" in capsys.readouterr().err and not (tmp_path / "q").exists()
