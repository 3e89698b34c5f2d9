"""The Snakemake workflow, really run: config validation, DAG, and the default target on the bundled data."""
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from snakemake_run import SNAKEMAKE
from snakemake_run import copy_workflow as _copy_workflow
from snakemake_run import run_snakemake as _run


def test_dry_run_with_a_dataset_plans_one_template_per_subject(tmp_path, sonicom):
    work = _copy_workflow(tmp_path)
    done = _run(["-n", "--cores", "2", "--config", f"data_root={sonicom}"], work)
    assert done.returncode == 0, done.stderr[-3000:]
    text = done.stdout + done.stderr
    for subject in ("P039", "P067", "P143"):
        assert f"results/templates/without_{subject}/template_left.ply" in text
        assert f"results/{subject}/align/summary.json" in text


def test_dry_run_with_hrtfs_plans_one_numcalc_job_per_ear_and_frequency_of_the_set(tmp_path, sonicom):
    """HRTFs on with the default frequency set (preset 'evaluation'): 40 NumCalc steps per ear and head."""
    import yaml

    work = _copy_workflow(tmp_path)
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["data_root"], config["hrtf"]["enabled"] = str(sonicom), True
    (work / "config" / "test_sets.yaml").write_text(yaml.safe_dump(config))
    done = _run(["results/P039/hrtf/ppm/HRIR.sofa", "-n", "--cores", "2", "--configfile",
                 "config/test_sets.yaml"], work)
    assert done.returncode == 0, done.stderr[-3000:]
    text = done.stdout + done.stderr
    for source in (1, 2):
        assert f"steps/source_{source}/steps_40-40.json" in text and f"steps/source_{source}/steps_41-41.json" not in text



def test_dry_run_of_the_evaluation_gives_each_control_only_to_its_listed_subjects(tmp_path, sonicom):
    """evaluation.own_pinna_subjects / default_ppm_subjects / ppm_detail_subjects / hard_subjects: the controls'
    heads are planned only for those, the *_hard ones from one defective scan per subject; never a condition that
    evaluation.not_solved says could not be built for the subject."""
    import re

    import yaml

    work = _copy_workflow(tmp_path)
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["data_root"], config["hrtf"]["enabled"] = str(sonicom), True
    config["evaluation"].update(conditions=["ppm", "own_pinna", "default_ppm", "ppm_detail", "ppm_hard",
                                            "ppm_detail_hard", "nricp_hard"], folder="evaluation/x",
                                own_pinna_subjects=["P143"], default_ppm_subjects=["P039"],
                                ppm_detail_subjects=["P067"], hard_subjects=["P143", "P039"],
                                not_solved={"P039": {"nricp_hard": "the stitch refused its pinna"}})
    (work / "config" / "test_controls.yaml").write_text(yaml.safe_dump(config))
    done = _run(["evaluation_report", "-n", "--cores", "2", "--configfile", "config/test_controls.yaml"], work)
    assert done.returncode == 0, done.stderr[-3000:]
    text = done.stdout + done.stderr
    planned = set(re.findall(r"results/(P\d+)/hrtf/(\w+)/HRIR\.sofa", text))
    assert planned == {("P039", "ppm"), ("P067", "ppm"), ("P143", "ppm"), ("P143", "own_pinna"),
                       ("P039", "default_ppm"), ("P067", "ppm_detail"), ("P143", "ppm_hard"),
                       ("P143", "ppm_detail_hard"), ("P143", "nricp_hard"), ("P039", "ppm_hard"),
                       ("P039", "ppm_detail_hard")}  # P039's nricp_hard: not solved
    assert set(re.findall(r"results/(P\d+)/controls/hard/scan\.ply", text)) == {"P143", "P039"}
    assert "evaluation/x/hard_scans" in text


def test_config_errors_stop_before_any_work(tmp_path):
    work = _copy_workflow(tmp_path)
    done = _run(["-n", "--cores", "1", "--config", f"data_root={tmp_path / 'nowhere'}"], work)
    assert done.returncode != 0
    assert "config key data_root=" in done.stdout + done.stderr
    done = _run(["-n", "--cores", "1", "--config", "template={'edge_mm': 0.01, 'margin_mm': 6, 'rounds': 2}"], work)
    assert done.returncode != 0
    assert "edge_mm" in done.stdout + done.stderr
    assert not (work / "results").exists()


def _demo_config(work: Path) -> Path:
    """The default demo, CI-sized: one subject (its 8 frequencies are the fewest that give the 16-sample
    HRIRs baumgartner2014 needs at a rate above 36 kHz)."""
    import yaml

    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["demo"]["subjects"] = 1
    path = work / "config" / "test_demo.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def test_default_run_makes_the_demo_through_every_stage(tmp_path):
    """`snakemake --cores 2` with no data: every output of every stage exists and parses."""
    import csv
    import json

    import sofar

    from ppm.parameters import PinnaParameters
    from reporting.subject import read_distances

    work = _copy_workflow(tmp_path)
    config = str(_demo_config(work))
    done = _run(["--cores", "2", "--configfile", config], work, timeout=1500)
    assert done.returncode == 0, (done.stdout + done.stderr)[-4000:]
    results = work / "results"
    # the PPM itself
    for name in ("default_ppm.png", "range_sheet.png"):
        assert (results / "ppm" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (results / "ppm" / "default_ppm.blend").stat().st_size > 100_000
    lines = (results / "ppm" / "default_parameters.csv").read_text().splitlines()
    assert lines[0].startswith("name,value") and len(lines) == 145
    # the demo subject
    subject, base = "demo01", results / "demo01"
    truth = PinnaParameters.read(results / "demo_data" / subject / "truth_parameters.json")
    assert json.loads((results / "demo_data" / subject / "demo.json").read_text())["fidelity"] == "demo"
    assert json.loads((base / "target" / "target.json").read_text())["n_points"] > 5000
    # alignment: close to the noisy scan and to the true parameters
    summary = json.loads((base / "align" / "summary.json").read_text())
    assert summary["distance_target_to_ppm"]["median_mm"] < 0.3  # mm; 0.2 mm scan noise
    fitted = PinnaParameters.read(base / "align" / "parameters.csv")
    assert fitted == PinnaParameters.read(base / "align" / "parameters.json")
    assert abs(fitted.to_dict()["Location_Size-Bendy_X"] - truth.to_dict()["Location_Size-Bendy_X"]) < 0.5  # mm
    # the demo crop's head skin lies right under the PPM's ring: left out of the target, but not pinna (no refit)
    assert summary["target_widening"]["refitted"] is False
    assert len(read_distances(base / "align" / "distances.ply")) == summary["distance_target_to_ppm"]["n_points"]
    assert trimesh.load(base / "align" / "aligned_pinna.ply", process=False).vertices.shape[0] > 5000
    # stitched and remeshed heads: closed and manifold
    for mesh in (base / "stitch" / "stitched_head.ply", base / "remesh" / "head.ply"):
        assert trimesh.load(mesh, process=False).is_watertight, mesh
    assert json.loads((base / "remesh" / "validation.json").read_text())["ok"] is True
    # HRTFs of both heads, SOFA files that pass sofar's checks
    for variant in ("reference", "ppm"):
        hrir = sofar.read_sofa(str(base / "hrtf" / variant / "HRIR.sofa"), verify=True)
        assert hrir.Data_IR.shape[1:] == (2, 16) and hrir.Data_SamplingRate == 40000.0
        assert np.isfinite(hrir.Data_IR).all()
        hrtf = sofar.read_sofa(str(base / "hrtf" / variant / "HRTF.sofa"), verify=True)
        assert hrtf.Data_Real.shape[2] == 8
    # localisation: the reference calibrated to 8 % quadrant errors
    localisation = json.loads((base / "localisation" / "qe_pe.json").read_text())
    assert abs(localisation["conditions"]["reference"]["qe_percent"] - 8.0) < 0.1
    assert 0 <= localisation["conditions"]["ppm"]["qe_percent"] <= 100
    # reports: self-contained, saying they are demo fidelity
    page = (base / "report.html").read_text()
    assert "Demo fidelity" in page and "Recovery of the true parameters" in page and "Cost of each stage" in page
    assert page.count("data:image/png;base64,") >= 7 and "not made" not in page
    rows = list(csv.DictReader((results / "dataset_summary.csv").open()))
    assert [r["subject"] for r in rows] == [subject] and float(rows[0]["solve_seconds_ppm"]) > 0
    assert len(list(csv.DictReader((results / "dataset_parameters.csv").open()))) == 144
    assert "Demo fidelity" in (results / "dataset_report.html").read_text()
    # a log per job, nothing half-written, and nothing left to do
    assert len(list((work / "logs").rglob("*.log"))) >= 12
    assert not [p for p in results.rglob("*") if "partial" in p.name or p.name.startswith(".tmp")]
    again = _run(["-n", "--cores", "2", "--configfile", config], work)
    assert "Nothing to be done" in again.stdout + again.stderr


def test_default_run_plans_the_demo_through_every_stage(tmp_path):
    work = _copy_workflow(tmp_path)
    done = _run(["-n", "--cores", "2"], work)
    assert done.returncode == 0, done.stderr[-3000:]
    text = done.stdout + done.stderr
    for rule in ("make_demo_subject", "prepare_target", "align_ppm", "stitch", "remesh", "export_project",
                 "solve_embedded", "collect_sofa", "localisation", "report_subject", "report_dataset"):
        assert f"rule {rule}:" in text


def _hrtf_config(work: Path, data_root: Path, solver: str, steps_per_job: int = 1,
                 frequencies_hz: dict | None = None) -> Path:
    import yaml

    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["data_root"] = str(data_root)
    config["hrtf"].update(solver=solver, frequencies_hz=frequencies_hz or {"min": 250.0, "max": 500.0, "step": 250.0},
                          polar_step_deg=10.0, steps_per_job=steps_per_job)
    path = work / "config" / "test_hrtf.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def test_hrtf_rules_export_solve_and_collect_a_sphere_head(tmp_path):
    """export_project -> solve_embedded -> collect_sofa on a 162-vertex sphere 'head' (2 frequencies, both
    ears), killed after its first step and resumed; with NumCalc as solver the DAG has one job per ear
    and frequency step."""
    import sofar

    work = _copy_workflow(tmp_path)
    subject = tmp_path / "data" / "S1"
    subject.mkdir(parents=True)
    head = trimesh.creation.icosphere(subdivisions=2, radius=87.5)
    head.export(subject / "head_graded_left.ply")
    head.export(subject / "pinna_left_crop.ply")  # makes S1 a subject; alignment is not requested here
    # the embedded solver takes all heads of a subject in one job: the sphere stands in for the PPM head too
    (work / "results/S1/remesh").mkdir(parents=True)
    head.export(work / "results/S1/remesh/head.ply")
    target = "results/S1/hrtf/reference/HRIR.sofa"
    hrtf_rules = ["--allowed-rules", "export_project", "solve_embedded", "solve_numcalc_step", "collect_sofa",
                  "band_head", "export_band_project"]  # NumCalc solves the low steps on band meshes (config.yaml)
    planned = _run([target, *hrtf_rules, "-n", "--cores", "2", "--configfile",
                    str(_hrtf_config(work, tmp_path / "data", "numcalc"))], work)
    assert planned.returncode == 0, planned.stderr[-3000:]
    text = planned.stdout + planned.stderr
    for source in (1, 2):
        for step in (1, 2):
            assert f"results/S1/hrtf/reference/steps/source_{source}/steps_{step}-{step}.json" in text
    grouped = _run([target, *hrtf_rules, "-n", "--cores", "2", "--configfile",
                    str(_hrtf_config(work, tmp_path / "data", "numcalc", steps_per_job=2))], work)
    assert "steps/source_2/steps_1-2.json" in grouped.stdout + grouped.stderr  # one job for both steps
    # kill the run once the first frequency step is on disk, then rerun: finished steps are kept
    import os
    import signal
    import time

    # 20 frequencies: after the first the others take a fraction of a second each on this small sphere
    config = str(_hrtf_config(work, tmp_path / "data", "embedded",
                              frequencies_hz={"min": 100.0, "max": 2000.0, "step": 100.0}))
    first_step = work / "results/S1/hrtf/reference/project/NumCalc/source_1/be.out/be.1/pEvalGrid"
    status = work / "results/S1/hrtf/embedded.json"
    killed = subprocess.Popen(SNAKEMAKE + [target, *hrtf_rules, "--cores", "2", "--configfile", config], cwd=work,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 600
    while not first_step.is_file() and time.time() < deadline and killed.poll() is None:
        time.sleep(0.05)
    os.killpg(killed.pid, signal.SIGKILL)
    killed.wait()
    assert first_step.is_file() and not status.exists()  # no declared output of the killed job
    assert not list(status.parent.glob("*.partial*")) if status.parent.exists() else True
    first_step_written = first_step.stat().st_mtime_ns
    assert _run([target, "--unlock", "--configfile", config], work).returncode == 0  # a SIGKILL leaves the lock
    done = _run([target, *hrtf_rules, "--cores", "2", "--rerun-incomplete", "--configfile", config], work, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    import json

    # step 1 of the left ear (and of the right one if it was written before the kill) was not redone
    assert 0 < json.loads(status.read_text())["projects"]["reference"]["steps_solved"] <= 38
    assert first_step.stat().st_mtime_ns == first_step_written
    hrir = sofar.read_sofa(str(work / target), verify=True)
    assert hrir.GLOBAL_SOFAConventions == "SimpleFreeFieldHRIR" and hrir.Data_IR.shape[1:] == (2, 40)
    hrtf = sofar.read_sofa(str(work / "results/S1/hrtf/reference/HRTF.sofa"), verify=True)
    assert hrtf.Data_Real.shape == (108, 2, 20)  # 3 planes x 36 polar angles, 2 ears, 20 frequencies
    assert (work / "logs/hrtf/solve_embedded/S1.log").is_file()
    again = _run([target, *hrtf_rules, "-n", "--cores", "2", "--configfile", str(work / "config" / "test_hrtf.yaml")], work)
    assert "Nothing to be done" in again.stdout + again.stderr


def test_localisation_rule_compares_ppm_and_reference_hrtfs(tmp_path, sonicom):
    """The localisation rule on real HRIR sets standing in for the reference and the PPM head."""
    import json

    hrtf_data = sonicom.parent / "hrtf"
    work = _copy_workflow(tmp_path)
    subject = tmp_path / "data" / "S1"
    subject.mkdir(parents=True)
    trimesh.creation.icosphere(subdivisions=1, radius=80.0).export(subject / "pinna_left_crop.ply")
    shutil.copy(hrtf_data / "measured_axd_example1.sofa", subject / "hrir_mesh2hrtf_48k.sofa")
    ppm = work / "results" / "S1" / "hrtf" / "ppm" / "HRIR.sofa"
    ppm.parent.mkdir(parents=True)
    shutil.copy(hrtf_data / "measured_axd_example2.sofa", ppm)
    target = "results/S1/localisation/qe_pe.json"
    done = _run([target, "--cores", "1", "--allowed-rules", "localisation", "--config",
                 f"data_root={tmp_path / 'data'}"], work)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    summary = json.loads((work / target).read_text())
    assert summary["conditions"]["reference"]["qe_percent"] == pytest.approx(8.0, abs=0.01)
    assert summary["conditions"]["ppm"]["qe_percent"] > 15.0
    # the default set is sparse: the dataset's full reference is sampled there and rebuilt, like with like
    assert summary["frequency_set"]["reference_rebuilt_at_set"] is True
    assert summary["frequency_set"]["description"].startswith("40 frequencies, 150 Hz to 24000 Hz")
    for name in ("qe_pe_bars.png", "reference_matrix.png", "ppm_matrix.png"):
        assert (work / "results/S1/localisation" / name).read_bytes()[:4] == b"\x89PNG"


def test_one_ear_on_the_reference_directions_is_collected_and_completed_by_the_reference(tmp_path, sonicom):
    """The paper's set-up on a sphere 'head': the left ear solved on the reference SOFA's 793 directions at the
    40-frequency evaluation set (embedded solver; with 10 frequencies the rebuilt reference could not reach 8 %
    QE any more), collected into one-ear SOFA files (HRTF and HRIR rebuilt at the reference's 48 kHz, 320 taps),
    and predicted with the reference's right ear."""
    import json

    import sofar
    import yaml

    work = _copy_workflow(tmp_path)
    subject = tmp_path / "data" / "S1"
    subject.mkdir(parents=True)
    head = trimesh.creation.icosphere(subdivisions=2, radius=87.5)
    head.export(subject / "head_graded_left.ply")
    head.export(subject / "pinna_left_crop.ply")
    shutil.copy(sonicom / "P039" / "hrir_mesh2hrtf_48k.sofa", subject / "hrir_mesh2hrtf_48k.sofa")
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["data_root"] = str(tmp_path / "data")
    config["hrtf"].update(enabled=True, solver="embedded", ears="left", grid="reference_sofa",
                          frequencies_hz="evaluation", step_store="store")
    path = work / "config" / "test_one_ear.yaml"
    path.write_text(yaml.safe_dump(config))
    # the sphere stands in for the PPM head: the localisation compares it with the reference; the packaged
    # template stands in for its fit (whose landmarks the export keeps with the head)
    (work / "results/S1/remesh").mkdir(parents=True)
    head.export(work / "results/S1/remesh/head.ply")
    from ppm.template.store import default_template_dir

    for folder, name in (("results/S1/align", "aligned_pinna.ply"), ("results/templates/without_S1", "landmarks.yaml")):
        (work / folder).mkdir(parents=True, exist_ok=True)
        shutil.copy(default_template_dir() / ("template_left.ply" if name.endswith(".ply") else name), work / folder / name)
    target = "results/S1/localisation/qe_pe.json"
    done = _run([target, "--cores", "2", "--configfile", str(path), "--allowed-rules", "export_project",
                 "solve_embedded", "collect_sofa", "localisation"], work, timeout=1500)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    hrtf = sofar.read_sofa(str(work / "results/S1/hrtf/ppm/HRTF.sofa"), verify=True)
    assert hrtf.Data_Real.shape == (793, 1, 40)
    hrir = sofar.read_sofa(str(work / "results/S1/hrtf/ppm/HRIR.sofa"), verify=True)
    assert hrir.Data_IR.shape == (793, 1, 320) and float(np.ravel(hrir.Data_SamplingRate)[0]) == 48000.0
    reference = sofar.read_sofa(str(subject / "hrir_mesh2hrtf_48k.sofa"), verify=False)
    assert np.allclose(hrtf.SourcePosition[:, :2] % 360, reference.SourcePosition[:, :2] % 360, atol=1e-6)
    summary = json.loads((work / target).read_text())
    assert summary["solved_ear"] == "left"
    assert summary["conditions"]["reference"]["qe_percent"] == pytest.approx(8.0, abs=0.01)
    assert summary["conditions"]["ppm"]["qe_percent"] > summary["conditions"]["reference"]["qe_percent"] + 5.0
    assert len(list((work / "store/S1/ppm/source_1").glob("step_*.npz"))) == 40
    # the head is kept beside its steps; a fresh clone without the rebuilt head exports the kept one and restores
    # every step instead of solving
    assert (work / "store/S1/ppm/head.ply").read_bytes() == (work / "results/S1/remesh/head.ply").read_bytes()
    from reporting.kept_fit import kept_fit_landmarks
    from reporting.pinna_regions import landmark_positions_mm

    fit = landmark_positions_mm(work / "results/S1/align/aligned_pinna.ply", default_template_dir() / "landmarks.yaml")
    assert kept_fit_landmarks(work / "store/S1/ppm")["concha_centre"] == pytest.approx(fit["concha_centre"], abs=1e-6)
    shutil.rmtree(work / "results/S1/remesh")
    shutil.rmtree(work / "results/S1/hrtf")
    shutil.rmtree(work / "results/S1/localisation")
    again = _run([target, "--cores", "2", "--configfile", str(path), "--allowed-rules", "export_project",
                  "solve_embedded", "collect_sofa", "localisation"], work, timeout=900)
    assert again.returncode == 0, (again.stdout + again.stderr)[-3000:]
    embedded = json.loads((work / "results/S1/hrtf/embedded.json").read_text())
    assert embedded["projects"]["ppm"]["steps_restored"] == 40
    assert json.loads((work / target).read_text())["conditions"]["ppm"] == summary["conditions"]["ppm"]
