"""Benchmark: agreement of amt_bridge's baumgartner2014 with AMT 0.9.10 run in GNU Octave.

Both get the same DTFs (computed by amt_bridge from the SOFA files); AMT then runs every stage from
the sagittal-plane extraction to QE/PE/EB. Needs octave on PATH and the AMT 0.9.10 and LTFAT 2.3.1
sources (give their folders). Without them it compares against the stored reference
``tests/references/b2014_amt_reference.npz`` instead (made by this script with --write-reference).

Run: .venv/bin/python benchmarks/amt_agreement.py [--amt DIR --ltfat DIR] [--write-reference]
Last line: JSON with the largest p difference and QE/PE differences over all pairs and planes.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import scipy.io

from amt_bridge import LocalisationModel, read_hrtf_set
from amt_bridge.dtf import hrtf_to_dtf

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
REFERENCE = ROOT / "tests" / "references" / "b2014_amt_reference.npz"
LATERAL_DEG = (-20.0, 0.0, 20.0)
SENSITIVITY_DB = 0.7
PAIRS = {  # name: (target, template), relative to ../shared/data
    "axd2_heard_by_axd1": ("hrtf/measured_axd_example2.sofa", "hrtf/measured_axd_example1.sofa"),
    "p039_simulated_self": ("sonicom/P039/hrir_mesh2hrtf_48k.sofa", "sonicom/P039/hrir_mesh2hrtf_48k.sofa"),
    "kemar44k_heard_by_irc1003": ("hrtf/measured_mit_kemar.sofa", "hrtf/measured_listen_irc1003.sofa"),
}


def _dtfs(pair):
    return tuple(hrtf_to_dtf(read_hrtf_set(DATA / path)) for path in pair)


def run_amt(amt: Path, ltfat: Path, target, template, workdir: Path) -> dict:
    """AMT's p, rang, tang, qe, pe, eb per lateral angle for these DTF sets."""
    def positions(h):
        return np.c_[h.azimuth_deg, h.elevation_deg, np.ones(h.azimuth_deg.size)]
    scipy.io.savemat(workdir / "in.mat", dict(tar_ir=target.irs, tem_ir=template.irs, fs_tar=target.sampling_rate_hz,
                                              fs_tem=template.sampling_rate_hz, tar_pos=positions(target),
                                              tem_pos=positions(template), lats=np.array(LATERAL_DEG),
                                              S=SENSITIVITY_DB))
    script = (f"addpath('{Path(__file__).parent / 'amt'}'); amt_b2014_reference('{amt}', '{ltfat}', "
              f"'{workdir / 'in.mat'}', '{workdir / 'out.mat'}')")
    subprocess.run(["octave", "--no-gui", "-q", "--eval", script], check=True, capture_output=True, text=True)
    out = scipy.io.loadmat(workdir / "out.mat")
    return {key: np.asarray(value, dtype=np.float64).squeeze() if not key.startswith("p") or key.startswith("pe")
            else np.asarray(value, dtype=np.float64) for key, value in out.items() if not key.startswith("__")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--amt", type=Path, help="AMT 0.9.10 source folder")
    parser.add_argument("--ltfat", type=Path, help="LTFAT 2.3.1 source folder")
    parser.add_argument("--write-reference", action="store_true", help=f"store AMT's results in {REFERENCE}")
    args = parser.parse_args()
    live = bool(args.amt and args.ltfat and shutil.which("octave"))
    stored = dict(np.load(REFERENCE)) if REFERENCE.is_file() and not live else {}
    if not live and not stored:
        raise SystemExit("give --amt and --ltfat (and install octave), or create the stored reference first")
    print(f"reference: {'AMT in Octave' if live else REFERENCE}")
    worst = {"p_max_abs_diff": 0.0, "qe_max_abs_diff_points": 0.0, "pe_max_abs_diff_deg": 0.0}
    to_store = {}
    for name, pair in PAIRS.items():
        target, template = _dtfs(pair)
        ours = LocalisationModel(target, template, LATERAL_DEG, already_dtf=True).predict(SENSITIVITY_DB)
        if live:
            with tempfile.TemporaryDirectory() as tmp:
                amt = run_amt(args.amt, args.ltfat, target, template, Path(tmp))
        else:
            amt = {key.split("/", 1)[1]: value for key, value in stored.items() if key.startswith(name + "/")}
        for k, plane in enumerate(ours.planes, start=1):
            p_amt = amt[f"p{k}"]
            p_diff = float(np.abs(p_amt - plane.p).max()) if p_amt.shape == plane.p.shape else float("inf")
            qe_diff = abs(float(amt[f"qe{k}"]) - plane.performance.qe_percent)
            pe_diff = abs(float(amt[f"pe{k}"]) - plane.performance.pe_deg)
            worst["p_max_abs_diff"] = max(worst["p_max_abs_diff"], p_diff)
            worst["qe_max_abs_diff_points"] = max(worst["qe_max_abs_diff_points"], qe_diff)
            worst["pe_max_abs_diff_deg"] = max(worst["pe_max_abs_diff_deg"], pe_diff)
            print(f"{name:28s} lateral {plane.lateral_deg:+5.0f} deg: QE {plane.performance.qe_percent:8.4f} % "
                  f"(AMT {float(amt[f'qe{k}']):8.4f}), PE {plane.performance.pe_deg:7.4f} deg "
                  f"(AMT {float(amt[f'pe{k}']):7.4f}), max |p - p_AMT| {p_diff:.1e}")
            for key in ("p", "rang", "tang", "qe", "pe", "eb"):
                to_store[f"{name}/{key}{k}"] = amt[f"{key}{k}"]
    if args.write_reference and live:
        REFERENCE.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(REFERENCE, **to_store)
        print(f"wrote {REFERENCE}")
    print(json.dumps({key: float(f"{value:.3g}") for key, value in worst.items()} | {"live_amt": live}))


if __name__ == "__main__":
    main()
