"""A new listener through the workflow, really run: a head scan (CGTUB's head, turned at random and written in cm,
as a user's scanner might export it) and a separate scan of its left ear in, the frame found, the ear scan
registered onto the head, both ears fitted by the PPM with the personal-detail layer, both fits stitched in and the head remeshed at both pinnae,
then, CI-sized, to the both-ear HRIRs and the report; a bad listener table stops the run before any work."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from mesh2hrtf_io.ear_canal import ear_canal_centre

from snakemake_run import copy_workflow as _project
from snakemake_run import run_snakemake


def _run(args: list[str], cwd: Path) -> object:
    return run_snakemake(args, cwd, timeout=900)


def test_a_bad_listener_table_stops_the_run(tmp_path):
    work = _project(tmp_path)
    done = _run(["-n", "--cores", "1", "--config", "listeners=[{name: me, head: scans/missing.stl}]"], work)
    assert done.returncode != 0 and "scans/missing.stl is missing or empty" in done.stdout + done.stderr
    (work / "scans").mkdir()
    (work / "scans" / "me.txt").write_text("not a mesh")
    done = _run(["-n", "--cores", "1", "--config", "listeners=[{name: me, head: scans/me.txt}]"], work)
    assert done.returncode != 0 and "not a mesh file" in done.stdout + done.stderr
    done = _run(["-n", "--cores", "1", "--config", "listeners=[{name: 'me too', head: scans/me.txt}]"], work)
    assert done.returncode != 0 and "name" in done.stdout + done.stderr
    assert not (work / "results").exists()


@pytest.mark.slow
def test_a_listener_gets_a_both_ear_hrir_set_on_the_full_grid(tmp_path, sonicom):
    """CI-sized (coarse bands, 8 frequencies, the embedded solver): CGTUB's head in cm and turned, with a separate
    scan of its left ear (the head's own ear cut out, turned otherwise, in mm), through to a SimpleFreeFieldHRIR
    file with both ears on the full grid (a source on the left is louder at the left ear) and the listener's
    report, where two SONICOM sets are heard with the listener's own template. The 1 mm remeshing of both pinnae
    (the real bands) is measured by benchmarks/new_listener.py on P143's head."""
    import sofar
    import yaml

    from listener.ears import pinna_crop

    work = _project(tmp_path)
    head = trimesh.load(sonicom.parent / "heads" / "cgtub_head_2mm.ply", process=False, force="mesh")
    rotation = Rotation.random(random_state=3).as_matrix()
    (work / "scans").mkdir()
    trimesh.Trimesh((np.asarray(head.vertices) @ rotation.T + [50.0, 20.0, -80.0]) / 10.0, head.faces,
                    process=False).export(work / "scans" / "cgtub.ply")
    ear = pinna_crop(head, "left")
    turn = Rotation.random(random_state=12).as_matrix()
    trimesh.Trimesh(np.asarray(ear.vertices) @ turn.T + [5.0, 9.0, -3.0], ear.faces,
                    process=False).export(work / "scans" / "cgtub_left_ear.ply")
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["listeners"] = [{"name": "cgtub", "head": "scans/cgtub.ply", "left_ear": "scans/cgtub_left_ear.ply"}]
    config["hrtf"].update(enabled=True, solver="embedded", embedded_threads=2, polar_step_deg=10.0,
                          frequencies_hz={"min": 1250.0, "max": 20000.0, "step": 2500.0})
    config["listener"]["comparison_sets"] = [str(sonicom / s / "hrir_mesh2hrtf_48k.sofa") for s in ("P039", "P067")]
    # a measured listener, as the evaluation's non-individual sets are given (reporting.nonindividual.MeasuredSet)
    config["listener"]["comparison_sets"].append({"name": "axd1", "kind": "listener",
                                                  "file": str(sonicom.parent / "hrtf" / "measured_axd_example1.sofa")})
    config["listener"]["personal_detail"] = True
    config["listener"]["dataset_grid"] = str(sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa")  # SONICOM's 793 too
    config["stitch"]["bands"] = config["demo"]["bands"]
    (work / "config" / "listener_ci.yaml").write_text(yaml.safe_dump(config))
    done = _run(["--cores", "2", "--configfile", "config/listener_ci.yaml"], work)
    assert done.returncode == 0, done.stderr[-4000:]
    base = work / "results" / "listeners" / "cgtub"
    frame = json.loads((base / "prepared" / "frame.json").read_text())
    assert frame["unit"] == "cm" and not frame["kept_as_given"]
    registration = json.loads((base / "prepared" / "ear_scan_left.json").read_text())
    assert registration["median_mm"] < 0.2 and registration["share_within_1mm"] > 0.95
    assert json.loads((base / "align" / "left" / "summary.json").read_text())["target"].endswith("pinna_target.ply")
    for side in ("left", "right"):
        fit = json.loads((base / "align" / side / "summary.json").read_text())
        assert fit["distance_target_to_ppm"]["median_mm"] < 0.5  # the packaged template fitted to CGTUB's ears
        assert (base / "align" / side / "aligned_pinna.blend").stat().st_size > 0
        # listener.personal_detail: the layer on each fit draws it onto its scan, and the stitch takes it
        detail = json.loads((base / "detail" / side / "summary.json").read_text())
        assert detail["ppm"]["median_mm"] == pytest.approx(fit["distance_target_to_ppm"]["median_mm"], abs=1e-3)
        assert detail["ppm_detail"]["median_mm"] < 0.6 * detail["ppm"]["median_mm"], detail
        assert detail["shape_key_mismatch_mm"] < 0.01
    assert "detail/left/aligned_pinna.ply" in (base / "stitch" / "stitch.json").read_text()
    remeshed = trimesh.load(base / "remesh" / "head.ply", process=False)
    assert remeshed.is_watertight
    # both ear canals of the remeshed head lie on the interaural axis the frame put them on (within 3 mm)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        centre = ear_canal_centre(remeshed, side)
        assert np.abs(centre[[0, 2]]).max() < 3.0 and 60.0 < sign * centre[1] < 75.0
    hrirs = sofar.read_sofa(work / "results/listeners/cgtub/hrtf/personal/HRIR.sofa", verify=False)
    assert hrirs.GLOBAL_SOFAConventions == "SimpleFreeFieldHRIR"
    # 17 sagittal planes of 36 polar angles each, and the SONICOM directions they lack (listener.dataset_grid)
    assert hrirs.Data_IR.shape[1] == 2 and 17 * 36 + 700 < hrirs.Data_IR.shape[0] <= 17 * 36 + 793
    positions, energy = hrirs.SourcePosition, (hrirs.Data_IR ** 2).sum(axis=-1)
    left = (positions[:, 0] > 60) & (positions[:, 0] < 120) & (np.abs(positions[:, 1]) < 30)
    right = (positions[:, 0] > 240) & (positions[:, 0] < 300) & (np.abs(positions[:, 1]) < 30)
    assert 10 * np.log10(energy[left, 0].mean() / energy[left, 1].mean()) > 10.0
    assert 10 * np.log10(energy[right, 1].mean() / energy[right, 0].mean()) > 10.0
    localisation = json.loads((work / "results/listeners/cgtub/localisation.json").read_text())
    assert set(localisation["sets"]) == {"own", "P039", "P067", "axd1"}
    assert localisation["sets"]["axd1"]["kind"] == "listener" and localisation["sets"]["P039"]["kind"] == "other person"
    # S calibrated on the dataset's 793 directions, and every comparison with a SONICOM set keeps all of them
    assert localisation["sets"]["own"]["directions"] == 793 and localisation["sets"]["P039"]["directions"] == 793
    assert all(np.isfinite(row["qe_percent"]) for row in localisation["sets"].values())
    page = (work / "results/listeners/cgtub/report.html").read_text()
    assert "What personalising buys" in page and "hrtf_planes.png" in page and "detail/left/aligned_pinna.blend" in page
    # what each ear's scan saw: a share per region of the fitted pinna, advice, a picture per ear
    coverage = json.loads((work / "results/listeners/cgtub/coverage.json").read_text())
    assert set(coverage["ears"]) == {"left", "right"} and coverage["advice"]
    whole = {side: next(r for r in rows if r["region"] == "whole pinna") for side, rows in coverage["ears"].items()}
    assert all(0.5 < row["seen_share"] <= 1.0 for row in whole.values())
    assert "What the scans saw" in page and (work / "results/listeners/cgtub/coverage_left.png").is_file()
