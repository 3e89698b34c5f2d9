"""Where in frequency each committed evaluation condition's left-ear DTFs leave the dataset's reference.

    .venv/bin/python studies/condition_dtf_gap.py [--evaluation evaluation/sonicom]

For every subject and solved condition in ``<evaluation>/summary.csv``, the committed left-ear HRTFs
(``sofa/<subject>_<condition>_left_HRTF.sofa``, solved at the evaluation frequency set) are compared with the
subject's reference HRIRs (``../shared/data/sonicom/<subject>/hrir_mesh2hrtf_48k.sofa``, left ear) sampled
exactly at the same frequencies (DFT of the impulse responses). DTF here: per frequency, the level in dB
with its mean over the 793 directions removed. Printed per frequency: the median and 95th percentile of
|ΔDTF| over the directions (dB), the common transfer function's gap (the part the DTF removes: the solved
set's level minus the reference's, averaged over the directions, dB, signed; what the source and the ear canal
and concha in front of it add to every direction alike), and the median over baumgartner2014's band (0.7-18 kHz).
Reads committed files only (seconds). Last line (JSON): per subject and condition the frequencies (Hz), the
per-frequency medians and p95 (dB), the common transfer function's gap (``ctf_gap_db``) and the band median (dB).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"
BAND_HZ = (700.0, 18000.0)  # baumgartner2014's default analysis band


LATERAL_BANDS_DEG = ((-90, -45), (-45, -15), (-15, 15), (15, 45), (45, 91))  # lateral angle, + towards the left
MID_BAND_HZ = (4000.0, 10300.0)


def lateral_angles_deg(source_position: np.ndarray) -> np.ndarray:
    """Lateral angle (deg, +90 = left) of SOFA spherical directions (azimuth, elevation in degrees)."""
    azimuth, elevation = np.radians(source_position[:, 0]), np.radians(source_position[:, 1])
    return np.degrees(np.arcsin(np.clip(np.cos(elevation) * np.sin(azimuth), -1.0, 1.0)))


def left_ear_gap(subject: str, sofa_path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz) of the solved set, |ΔDTF| (dB), (directions, K), and the common transfer function's gap
    (dB, (K,), solved minus reference, level averaged over the directions), against the reference's left ear."""
    import sofar

    from amt_bridge.dtf import directional_levels_db
    from mesh2hrtf_io.sparse_hrtf import sample_spectra

    solved = sofar.read_sofa(str(sofa_path), verify=False)
    reference = sofar.read_sofa(str(SONICOM / subject / "hrir_mesh2hrtf_48k.sofa"), verify=False)
    if not np.allclose(solved.SourcePosition[:, :2], reference.SourcePosition[:, :2], atol=1e-3):
        raise SystemExit(f"{sofa_path}: its directions are not the reference's ({subject})")
    frequencies = np.asarray(solved.N, dtype=np.float64)
    spectra = solved.Data_Real[:, 0, :] + 1j * solved.Data_Imag[:, 0, :]
    rate = float(np.squeeze(reference.Data_SamplingRate))
    exact = sample_spectra(reference.Data_IR[:, 0, :], rate, frequencies)
    dtf_gap = np.abs(directional_levels_db(spectra) - directional_levels_db(exact))
    ctf_gap = (_levels_db(spectra) - _levels_db(exact)).mean(axis=0)
    return frequencies, dtf_gap, ctf_gap


def directions_of(subject: str) -> np.ndarray:
    """The reference SOFA's source positions (azimuth, elevation in degrees, distance)."""
    import sofar

    return np.asarray(sofar.read_sofa(str(SONICOM / subject / "hrir_mesh2hrtf_48k.sofa"), verify=False).SourcePosition)


def _levels_db(spectra: np.ndarray) -> np.ndarray:
    """Levels (dB) of complex spectra."""
    return 20.0 * np.log10(np.abs(spectra) + 1e-20)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    args = parser.parse_args()
    from reporting.evaluation_files import left_hrtf_name

    rows = list(csv.DictReader((args.evaluation / "summary.csv").open()))
    figures = {}
    for row in rows:
        subject, condition = row["subject"], row["condition"]
        if condition == "reference":
            continue
        frequencies, gap, ctf_gap = left_ear_gap(subject, args.evaluation / "sofa" / left_hrtf_name(subject, condition))
        median, p95 = np.median(gap, axis=0), np.percentile(gap, 95, axis=0)
        band = (frequencies >= BAND_HZ[0]) & (frequencies <= BAND_HZ[1])
        band_median = float(np.median(gap[:, band]))
        print(f"{subject} {condition}: |ΔDTF| vs the reference, median (p95) over 793 directions, dB, and the "
              f"common transfer function's gap (dB); |ΔDTF| over 0.7-18 kHz {band_median:.2f} dB")
        for f, m, p, c in zip(frequencies, median, p95, ctf_gap):
            print(f"  {f / 1000:6.2f} kHz  {m:5.2f}  ({p:5.2f})  CTF {c:+6.2f}")
        lateral = lateral_angles_deg(directions_of(subject))
        mid = (frequencies >= MID_BAND_HZ[0]) & (frequencies <= MID_BAND_HZ[1])
        by_lateral = {f"{lo}..{hi}": round(float(np.median(gap[(lateral >= lo) & (lateral < hi)][:, mid])), 3)
                      for lo, hi in LATERAL_BANDS_DEG}
        print("  median |ΔDTF| over 4-10.3 kHz by lateral angle (deg): "
              + ", ".join(f"{k}: {v:.2f} dB" for k, v in by_lateral.items()))
        figures[f"{subject}_{condition}"] = {"frequencies_hz": [round(float(f), 1) for f in frequencies],
                                             "median_db": [round(float(m), 3) for m in median],
                                             "p95_db": [round(float(p), 3) for p in p95],
                                             "ctf_gap_db": [round(float(c), 3) for c in ctf_gap],
                                             "mid_band_median_db_by_lateral_deg": by_lateral,
                                             "band_median_db": round(band_median, 3)}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
