"""What the new listener's personal sets change in the DTFs the model hears, against the head as scanned.

    .venv/bin/python studies/listener_dtf_gap.py [--subject P143]

Every solved listener of ``benchmarks/new_listener.py`` (``results/listeners/<subject>_<kind>/hrtf/personal/
HRTF.sofa``: the clean head scan ``new``, its layer variants, and the placed hard listeners with their layer variants
and draws; :data:`KINDS`) against the head as scanned (``results/listeners/<subject>_new/hrtf/scanned/HRTF.sofa``,
the paper protocol's reference), both ears, on the dataset's directions
(``../shared/data/sonicom/<subject>/hrir_mesh2hrtf_48k.sofa``, each within 0.5 deg) and within 30 deg of the median
plane (the model's sagittal planes lie at -20, 0 and +20 deg). DTF: per ear and frequency, the level (dB) minus its
mean over those directions. Per band of ``BAND_EDGES_HZ``:

- ``gap_db``: the median over directions and ears of |ΔDTF| (dB), personal minus scanned;
- ``contrast``: the DTF's spread over directions (standard deviation, dB), personal over scanned (1 = as deep and
  as high as the scanned ear's cues; below 1 flatter), the median over the band's frequencies and both ears;
- ``notch_shift_percent``: in front (the same directions, polar -30 to +45 deg), the deepest DTF
  minimum between 5 and 13 kHz (the first pinna notch, parabola through the three bins nearest it on log frequency),
  personal against scanned, median |Δf| / f over directions and ears (%).

It prints these with each listener's ΔQE / ΔPE by the paper's protocol (``benchmarks/results/new_listener/
<subject>.json``) and, over the hard listeners, the rank correlation of each band's gap with ΔQE. Reads the run
folders of ``benchmarks/new_listener.py`` (results/ is not committed; the benchmark rebuilds them from the step store
in minutes). Last line (JSON): per kind the figures above and the correlations.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"
KEPT = ROOT / "benchmarks" / "results" / "new_listener"
from new_listener import CLEAN_VARIANT_KINDS, HARD_KINDS  # noqa: E402

#: The benchmark's listeners on the head scan's own frame: the clean one, its layer variants, and the placed hard ones
#: (the registered hard listeners carry the registration's error besides the ears').
KINDS = ("new", *CLEAN_VARIANT_KINDS, *(kind for kind in HARD_KINDS if "placed" in kind))
BAND_EDGES_HZ = (700.0, 4400.0, 6000.0, 8500.0, 10300.0, 13000.0, 18000.0)
SAGITTAL_REACH_DEG = 30.0
NOTCH_RANGE_HZ = (5000.0, 13000.0)
TOLERANCE_DEG = 0.5


def read_set(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies Hz, complex spectra (directions, 2 ears, K), SOFA source positions (deg)) of an HRTF SOFA."""
    import sofar

    if not path.is_file():
        raise FileNotFoundError(path)
    with contextlib.redirect_stdout(io.StringIO()):  # sofar prints the solver's custom entries
        sofa = sofar.read_sofa(str(path), verify=False)
    return (np.asarray(sofa.N, dtype=np.float64), sofa.Data_Real + 1j * sofa.Data_Imag,
            np.asarray(sofa.SourcePosition, dtype=np.float64))


def unit_vectors(positions_deg: np.ndarray) -> np.ndarray:
    """Unit vectors (x front, y left, z up) of SOFA spherical positions (azimuth, elevation in degrees)."""
    azimuth, elevation = np.radians(positions_deg[:, 0]), np.radians(positions_deg[:, 1])
    return np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)


def rows_on(positions_deg: np.ndarray, wanted_deg: np.ndarray) -> np.ndarray:
    """Row of ``positions_deg`` nearest each wanted direction; refuses a grid that lacks one within 0.5 deg."""
    from scipy.spatial import cKDTree

    distance, nearest = cKDTree(unit_vectors(positions_deg)).query(unit_vectors(wanted_deg))
    missing = int(np.sum(distance > 2.0 * np.sin(np.radians(TOLERANCE_DEG) / 2.0)))  # chord of the tolerance
    if missing:
        raise SystemExit(f"a listener's grid lacks {missing} of the dataset's directions; solve it with "
                         "listener.dataset_grid")
    return nearest


def lateral_polar_deg(positions_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interaural-polar coordinates (deg): lateral (+90 left) and polar (0 front, 90 above, 180 behind)."""
    x, y, z = unit_vectors(positions_deg).T
    return np.degrees(np.arcsin(np.clip(y, -1.0, 1.0))), np.degrees(np.arctan2(z, x))


def notch_hz(dtf: np.ndarray, frequencies_hz: np.ndarray) -> np.ndarray:
    """The deepest DTF minimum (Hz) in NOTCH_RANGE_HZ of each row (directions x K), refined by a parabola through
    the three bins around it on log frequency."""
    inside = np.flatnonzero((frequencies_hz >= NOTCH_RANGE_HZ[0]) & (frequencies_hz <= NOTCH_RANGE_HZ[1]))
    log_f = np.log(frequencies_hz)
    found = np.empty(dtf.shape[0])
    for row, levels in enumerate(dtf):
        k = inside[np.argmin(levels[inside])]
        if 0 < k < len(frequencies_hz) - 1:
            x, y = log_f[k - 1:k + 2], levels[k - 1:k + 2]
            a, b, _ = np.polyfit(x, y, 2)
            found[row] = np.exp(-b / (2.0 * a)) if a > 0 else frequencies_hz[k]
            found[row] = float(np.clip(found[row], frequencies_hz[k - 1], frequencies_hz[k + 1]))
        else:
            found[row] = frequencies_hz[k]
    return found


def spearman(x: list[float], y: list[float]) -> float:
    """Spearman's rank correlation of two equal-length lists."""
    from scipy.stats import spearmanr

    return float(spearmanr(x, y).statistic)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--subject", default="P143")
    args = parser.parse_args()
    subject = args.subject
    base = ROOT / "results" / "listeners"
    import sofar

    from amt_bridge.dtf import directional_levels_db

    dataset = np.asarray(sofar.read_sofa(str(SONICOM / subject / "hrir_mesh2hrtf_48k.sofa"),
                                         verify=False).SourcePosition, dtype=np.float64)
    lateral, polar = lateral_polar_deg(dataset)
    sagittal = np.abs(lateral) <= SAGITTAL_REACH_DEG
    frontal = sagittal & (polar >= -30.0) & (polar <= 45.0)
    frequencies, scanned, positions = read_set(base / f"{subject}_new" / "hrtf" / "scanned" / "HRTF.sofa")
    scanned = scanned[rows_on(positions, dataset)]
    kept = json.loads((KEPT / f"{subject}.json").read_text()) if (KEPT / f"{subject}.json").is_file() else {}
    bands = list(zip(BAND_EDGES_HZ[:-1], BAND_EDGES_HZ[1:]))
    scanned_dtf = directional_levels_db(scanned[sagittal])
    scanned_notch = np.concatenate([notch_hz(scanned_dtf[frontal[sagittal], ear], frequencies) for ear in (0, 1)])
    figures: dict = {}
    print(f"{subject}: personal sets against the head as scanned, both ears, {int(sagittal.sum())} dataset directions "
          f"within {SAGITTAL_REACH_DEG:g} deg of the median plane ({int(frontal.sum())} of them in front, "
          "polar -30 to +45 deg, for the notch)")
    print("bands (kHz): " + ", ".join(f"{lo / 1000:g}-{hi / 1000:g}" for lo, hi in bands))
    for kind in KINDS:
        path = base / f"{subject}_{kind}" / "hrtf" / "personal" / "HRTF.sofa"
        if not path.is_file():
            print(f"{kind}: not solved here ({path.relative_to(ROOT)})")
            continue
        kind_frequencies, spectra, positions = read_set(path)
        if not np.allclose(kind_frequencies, frequencies):
            raise SystemExit(f"{path}: its frequencies are not the scanned head's")
        dtf = directional_levels_db(spectra[rows_on(positions, dataset)][sagittal])
        gap = np.abs(dtf - scanned_dtf)
        contrast = dtf.std(axis=0) / scanned_dtf.std(axis=0)  # (2 ears, K)
        row = {"gap_db": [], "contrast": []}
        for lo, hi in bands:
            inside = (frequencies >= lo) & (frequencies < hi)
            row["gap_db"].append(round(float(np.median(gap[:, :, inside])), 3))
            row["contrast"].append(round(float(np.median(contrast[:, inside])), 3))
        notch = np.concatenate([notch_hz(dtf[frontal[sagittal], ear], frequencies) for ear in (0, 1)])
        row["notch_shift_percent"] = round(float(np.median(np.abs(notch / scanned_notch - 1.0)) * 100.0), 2)
        row["notch_median_hz"] = round(float(np.median(notch)), 0)
        row["delta_qe_pp"] = kept.get("paper_delta_qe_pp" if kind == "new" else f"{kind}_paper_delta_qe_pp")
        row["delta_pe_deg"] = kept.get("paper_delta_pe_deg" if kind == "new" else f"{kind}_paper_delta_pe_deg")
        figures[kind] = row
        qe = ("not judged" if row["delta_qe_pp"] is None
              else f"{row['delta_qe_pp']:+.2f} pp / {row['delta_pe_deg']:+.2f} deg")
        print(f"{kind:20s} {qe}: |ΔDTF| " + " ".join(f"{g:.2f}" for g in row["gap_db"]) + " dB; contrast "
              + " ".join(f"{c:.2f}" for c in row["contrast"]) + f"; first notch {row['notch_median_hz']:.0f} Hz "
              f"(scanned {np.median(scanned_notch):.0f}), shifted {row['notch_shift_percent']:.1f} %")
    hard = [kind for kind in figures if kind.startswith("hard") and figures[kind]["delta_qe_pp"] is not None]
    correlations = {}
    if len(hard) >= 4:
        qe = [figures[kind]["delta_qe_pp"] for kind in hard]
        correlations = {f"{lo / 1000:g}-{hi / 1000:g}": round(spearman([figures[k]["gap_db"][i] for k in hard], qe), 3)
                        for i, (lo, hi) in enumerate(bands)}
        correlations["notch_shift"] = round(spearman([figures[k]["notch_shift_percent"] for k in hard], qe), 3)
        print(f"rank correlation with ΔQE over the {len(hard)} hard listeners: "
              + ", ".join(f"{k}: {v:+.2f}" for k, v in correlations.items()))
    print(json.dumps({"subject": subject, "band_edges_hz": list(BAND_EDGES_HZ),
                      "scanned_notch_median_hz": round(float(np.median(scanned_notch)), 0), "kinds": figures,
                      "rank_correlation_with_delta_qe": correlations}))


if __name__ == "__main__":
    main()
