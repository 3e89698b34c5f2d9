"""Which speed of sound the dataset's reference HRTFs were solved with, inferred from the committed solves.

    .venv/bin/python studies/speed_of_sound.py [--evaluation evaluation/sonicom] [--subject P143]

A rigid head's referenced HRTF (ear pressure over the free-field pressure of a point source with the ear's volume
velocity) depends on frequency f and speed of sound c only through k = 2πf/c. So HRTFs solved at f with this
pipeline's c0 = 346.18 m/s (Mesh2HRTF's exporter default) are exactly the HRTFs of the same head solved with c at
f·c/c0. For the committed solves of the unchanged reference head (``original``) and of its own pinna put back
(``own_pinna``), this compares their left-ear DTFs (dB, the mean over the 793 directions removed per frequency)
with the reference's at f·c/c0 (the reference HRIRs' exact DFT) for c from 336 to 350 m/s, and prints the RMS gap
per band and the c that minimises it. Then QE and PE (baumgartner2014, S calibrated on the reference rebuilt at the
same frequencies, the reference as template, right ear from the reference) of every committed condition, as if
this pipeline had solved with c = 343.18 m/s (the speed of sound of Mesh2HRTF's own HRTF tutorial) or with the
best-fitting c. Reads committed files only (about a minute).

Last line (JSON): ``best_speed_of_sound_m_s`` (2-10.3 kHz band, ``original``), ``gap_rms_db`` per condition, band
and c (346.18, 343.18 and the best), and ``predictions``: per c and condition ``qe_percent`` / ``pe_deg`` /
``delta_qe_pp`` / ``delta_pe_deg`` against the reference.
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from committed import committed_subject, subject_arguments

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
BANDS_HZ = {"2-10.3kHz": (2000.0, 10300.0), "10.3-18kHz": (10300.0, 18000.0), "0.7-18kHz": (700.0, 18000.0)}
TUTORIAL_M_S = 343.18  # Mesh2HRTF 1.2.4's HRTF tutorial script
SCAN_M_S = np.unique(np.r_[np.arange(336.0, 350.01, 0.5), TUTORIAL_M_S, 346.18])


def gap_by_speed(solved_sofa: Path, reference_sofa: Path) -> dict[float, dict[str, float]]:
    """RMS |ΔDTF| (dB) per band between the left ear solved at c0 and the reference, for each c of the scan."""
    import sofar

    from amt_bridge.dtf import directional_levels_db
    from mesh2hrtf_io.constants import SPEED_OF_SOUND_M_S
    from mesh2hrtf_io.sparse_hrtf import sample_spectra

    solved = sofar.read_sofa(str(solved_sofa), verify=False)
    reference = sofar.read_sofa(str(reference_sofa), verify=False)
    frequencies = np.asarray(solved.N, dtype=np.float64)
    levels = directional_levels_db(solved.Data_Real[:, 0, :] + 1j * solved.Data_Imag[:, 0, :])
    rate = float(np.ravel(reference.Data_SamplingRate)[0])
    table = {}
    for c in SCAN_M_S:
        exact = sample_spectra(reference.Data_IR[:, 0, :], rate, frequencies * c / SPEED_OF_SOUND_M_S)
        gap = levels - directional_levels_db(exact)
        table[float(c)] = {band: float(np.sqrt(np.mean(gap[:, (frequencies >= lo) & (frequencies <= hi)] ** 2)))
                           for band, (lo, hi) in BANDS_HZ.items()}
    return table


def predictions_at(c: float, files: dict[str, Path], reference_sofa: Path, settings: dict) -> dict[str, dict]:
    """QE/PE of every condition as if solved with speed of sound ``c``: the same HRTFs relabelled to f·c/c0."""
    import sofar

    from amt_bridge.evaluation import compare_conditions
    from mesh2hrtf_io.constants import SPEED_OF_SOUND_M_S

    with tempfile.TemporaryDirectory() as tmp:
        relabelled = {}
        for condition, path in files.items():
            sofa = sofar.read_sofa(str(path), verify=False)
            sofa.N = np.asarray(sofa.N, dtype=np.float64) * c / SPEED_OF_SOUND_M_S
            relabelled[condition] = Path(tmp) / path.name
            sofar.write_sofa(str(relabelled[condition]), sofa, compression=0)
            frequencies = sofa.N
        sensitivity, predictions = compare_conditions(reference_sofa, relabelled, settings["calibration_qe_percent"],
                                                      settings["lateral_angles_deg"], frequencies, "left")
    reference = predictions["reference"]
    return {name: {"qe_percent": round(float(p.qe), 3), "pe_deg": round(float(p.pe), 3),
                   "delta_qe_pp": round(float(p.qe - reference.qe), 3),
                   "delta_pe_deg": round(float(p.pe - reference.pe), 3), "sensitivity_db": round(sensitivity, 3)}
            for name, p in predictions.items()}


def main() -> None:
    args = subject_arguments(__doc__)

    from mesh2hrtf_io.constants import SPEED_OF_SOUND_M_S

    settings, reference_sofa, files = committed_subject(args.evaluation, args.subject)
    figures: dict = {"subject": args.subject, "solved_with_m_s": SPEED_OF_SOUND_M_S, "gap_rms_db": {}}
    best = None
    for condition in ("original", "own_pinna"):
        if condition not in files:
            continue
        table = gap_by_speed(files[condition], reference_sofa)
        scan = np.array([table[float(c)]["2-10.3kHz"] for c in SCAN_M_S])
        fitted = float(SCAN_M_S[scan.argmin()])
        best = fitted if condition == "original" else best
        print(f"{args.subject} {condition}: RMS |ΔDTF| to the reference (dB) if solved with c instead of "
              f"{SPEED_OF_SOUND_M_S:g} m/s; best c over 2-10.3 kHz: {fitted:g} m/s")
        for c in SCAN_M_S:
            if c % 1.0 and c not in (TUTORIAL_M_S, SPEED_OF_SOUND_M_S, fitted):
                continue  # the printout every 1 m/s and at the c's that matter
            row = table[float(c)]
            print(f"  c = {c:6.2f} m/s  " + "  ".join(f"{band} {row[band]:.3f}" for band in BANDS_HZ))
        figures["gap_rms_db"][condition] = {f"{c:g}": {b: round(v, 3) for b, v in table[c].items()}
                                            for c in sorted({SPEED_OF_SOUND_M_S, TUTORIAL_M_S, fitted})}
        figures[f"{condition}_best_speed_of_sound_m_s"] = fitted
    figures["best_speed_of_sound_m_s"] = best
    figures["predictions"] = {}
    for c in sorted({SPEED_OF_SOUND_M_S, TUTORIAL_M_S, best}):
        rows = predictions_at(c, files, reference_sofa, settings)
        figures["predictions"][f"{c:g}"] = rows
        print(f"QE/PE as if solved with c = {c:g} m/s (S = {rows['reference']['sensitivity_db']:.3f} dB):")
        for name, row in rows.items():
            print(f"  {name:10s} QE {row['qe_percent']:7.3f} %  PE {row['pe_deg']:7.3f} deg  "
                  f"ΔQE {row['delta_qe_pp']:+6.3f} pp  ΔPE {row['delta_pe_deg']:+6.3f} deg")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
