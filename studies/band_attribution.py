"""Which frequency band carries a condition's QE/PE difference: one band of DTFs swapped at a time.

    .venv/bin/python studies/band_attribution.py [--evaluation evaluation/sonicom] [--subject P143]

Base: the committed left-ear HRTFs of the subject's unchanged head solved here (``original``; where that is not
solved yet, its own pinna cut out and put back, ``own_pinna``, which on P143 is 0.03 pp from it). Donors: the dataset's
reference (its HRIRs' exact DFT at the evaluation frequencies) and every other committed condition (``ppm``,
``own_pinna``, ...). For each donor and band, the base keeps its own HRTFs except in that band, where its directional
part is the donor's: level (dB) = base level - base DTF + donor DTF, DTF meaning the level minus its mean over the
793 directions (so the base's direction-independent part, and its phase, stay). Then QE and PE (baumgartner2014,
S calibrated on the reference rebuilt at the same frequencies, the reference as template, right ear from the
reference, as in the evaluation) of that hybrid, minus the base's own. Summed over the bands this approximates
the donor's whole difference from the base (printed as "all bands"; bands interact, so the sum is not exact).

Answers: in which band does the PPM's miss lie (the donor ``ppm``), and in which does the floor between this
pipeline's solve of the unchanged head and the dataset's reference lie (the donor ``reference``, with the sign
turned: what the base gains by taking the reference's DTFs there). Reads committed files only (about a minute).

Last line (JSON): ``subject``, ``base`` QE/PE, and per donor and band ``delta_qe_pp`` / ``delta_pe_deg`` (hybrid
minus base), with the band edges in Hz.
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
BAND_EDGES_HZ = (0.0, 4400.0, 6000.0, 8500.0, 10300.0, 13000.0, 18000.0, 24001.0)
ALL = (0.0, 24001.0)
BASES = ("original", "own_pinna")


def left_spectra(sofa) -> np.ndarray:
    """Complex left-ear spectra (directions, frequencies) of a SimpleFreeFieldHRTF object."""
    return sofa.Data_Real[:, 0, :] + 1j * sofa.Data_Imag[:, 0, :]


def hybrid(base: np.ndarray, donor: np.ndarray, frequencies_hz: np.ndarray, band_hz: tuple[float, float]) -> np.ndarray:
    """The base spectra with the donor's DTF (dB, direction mean removed per frequency) inside ``band_hz``."""
    from amt_bridge.dtf import directional_levels_db

    inside = (frequencies_hz >= band_hz[0]) & (frequencies_hz < band_hz[1])
    change_db = directional_levels_db(donor) - directional_levels_db(base)
    gain = np.where(inside[None, :], 10.0 ** (change_db / 20.0), 1.0)
    return base * gain


def predictions(base_sofa: Path, spectra: dict[str, np.ndarray], reference_sofa: Path, settings: dict) -> dict:
    """QE (%) and PE (deg) of the reference and of every named left-ear spectra set (written over the base file)."""
    import sofar

    from amt_bridge.evaluation import compare_conditions

    template = sofar.read_sofa(str(base_sofa), verify=False)
    frequencies = np.asarray(template.N, dtype=np.float64)
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        for name, values in spectra.items():
            template.Data_Real = values.real[:, None, :]
            template.Data_Imag = values.imag[:, None, :]
            files[name] = Path(tmp) / f"{name}.sofa"
            sofar.write_sofa(str(files[name]), template, compression=0)
        _, result = compare_conditions(reference_sofa, files, settings["calibration_qe_percent"],
                                       settings["lateral_angles_deg"], frequencies, "left")
    return {name: (float(p.qe), float(p.pe)) for name, p in result.items()}


def band_label(band: tuple[float, float]) -> str:
    if band == ALL:
        return "all bands"
    return f"{band[0] / 1000:g}-{min(band[1], 24000.0) / 1000:g} kHz"


def main() -> None:
    args = subject_arguments(__doc__)

    import sofar

    from mesh2hrtf_io.sparse_hrtf import sample_spectra

    settings, reference_sofa, files = committed_subject(args.evaluation, args.subject, needs=BASES)
    # the subject's own pinna solved here: the unchanged head, else the own-pinna control (P143: 0.03 pp apart)
    base_name = next(name for name in BASES if name in files)
    base_sofa = sofar.read_sofa(str(files[base_name]), verify=False)
    frequencies = np.asarray(base_sofa.N, dtype=np.float64)
    base = left_spectra(base_sofa)
    reference = sofar.read_sofa(str(reference_sofa), verify=False)
    donors = {"reference": sample_spectra(reference.Data_IR[:, 0, :], float(np.squeeze(reference.Data_SamplingRate)),
                                          frequencies)}
    donors.update({name: left_spectra(sofar.read_sofa(str(path), verify=False))
                   for name, path in files.items() if name != base_name})
    bands = list(zip(BAND_EDGES_HZ[:-1], BAND_EDGES_HZ[1:]))

    spectra = {"base": base}
    for donor, values in donors.items():
        for index, band in enumerate(bands + [ALL]):
            spectra[f"{donor}:{index}"] = hybrid(base, values, frequencies, band)
    result = predictions(files[base_name], spectra, reference_sofa, settings)
    base_qe, base_pe = result["base"]
    print(f"{args.subject}: base = {base_name} (solved here) QE {base_qe:.3f} %, PE {base_pe:.3f} deg; reference QE "
          f"{result['reference'][0]:.3f} %, PE {result['reference'][1]:.3f} deg")
    figures = {"subject": args.subject, "base_condition": base_name, "base": {"qe_percent": round(base_qe, 3), "pe_deg": round(base_pe, 3)},
               "band_edges_hz": list(BAND_EDGES_HZ[:-1]) + [24000.0], "donors": {}}
    for donor in donors:
        print(f"  {base_name} with {donor}'s DTFs in one band: ΔQE (pp), ΔPE (deg) against {base_name} itself")
        rows = {}
        for index, band in enumerate(bands + [ALL]):
            qe, pe = result[f"{donor}:{index}"]
            rows[band_label(band)] = {"delta_qe_pp": round(qe - base_qe, 3), "delta_pe_deg": round(pe - base_pe, 3)}
            print(f"    {band_label(band):14s} {qe - base_qe:+7.3f}  {pe - base_pe:+7.3f}")
        summed_qe = sum(row["delta_qe_pp"] for label, row in rows.items() if label != "all bands")
        summed_pe = sum(row["delta_pe_deg"] for label, row in rows.items() if label != "all bands")
        print(f"    {'sum of bands':14s} {summed_qe:+7.3f}  {summed_pe:+7.3f}")
        figures["donors"][donor] = rows
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
