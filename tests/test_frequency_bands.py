"""stitching.frequency_bands: a coarser mesh of a real head for a band of low frequencies keeps the ear-canal
source's triangles exactly and the surface closed, with far fewer elements."""
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from mesh2hrtf_io.checks import min_angles_deg
from mesh2hrtf_io.ear_canal import ear_canal_elements
from stitching.frequency_bands import band_mesh
from stitching.remesh import Band


def test_a_band_mesh_of_a_real_head_keeps_the_source(sonicom):
    head = trimesh.load(sonicom / "P143" / "head_graded_left.ply", process=False, force="mesh")
    pinna = np.asarray(trimesh.load(sonicom / "P143" / "pinna_left_crop.ply", process=False).vertices)
    source = ear_canal_elements(head, "left")
    bands = (Band(12.0, 3.0, 0.3), Band(30.0, 5.0, 0.5), Band(60.0, 8.0, 0.8), Band(np.inf, 12.0, 1.2))
    mesh, kept = band_mesh(head, source, pinna, bands, source="P143")
    assert len(mesh.faces) < 0.4 * len(head.faces)  # 31,466 -> about 9,000
    assert mesh.is_watertight and mesh.is_winding_consistent
    np.testing.assert_allclose(mesh.triangles_center[kept], head.triangles_center[source], atol=1e-9)
    assert mesh.area_faces[kept].sum() == pytest.approx(head.area_faces[source].sum(), rel=1e-12)
    assert min_angles_deg(mesh.vertices, mesh.faces).min() > 5.0
    # the surface stays where it was: every band-mesh vertex within the coarsest band's deviation of the head
    assert trimesh.proximity.closest_point(head, mesh.vertices[::20])[1].max() < 1.2


def test_a_banded_head_is_solved_per_band_and_collected_as_one(tmp_path):
    """The workflow with hrtf.frequency_bands and NumCalc on a sphere 'head' (2 frequencies, both ears): the step of
    the low band is solved in the band mesh's project and merged into the full project, the other on the full mesh,
    and one HRIR file comes out. Needs NumCalc (skipped where it is not installed)."""
    import json
    import subprocess
    import sys

    import sofar
    import yaml

    from mesh2hrtf_io.numcalc import NumCalcError, find_numcalc
    from mesh2hrtf_io.results import read_eval_grid_pressure

    try:
        numcalc = find_numcalc()
    except NumCalcError as exc:
        pytest.skip(str(exc))
    root = Path(__file__).resolve().parents[1]
    work = tmp_path / "project"
    for folder in ("workflow", "rules", "config"):
        shutil.copytree(root / folder, work / folder)
    subject = tmp_path / "data" / "S1"
    subject.mkdir(parents=True)
    head = trimesh.creation.icosphere(subdivisions=3, radius=87.5)  # 1,280 faces of ~14 mm
    head.export(subject / "head_graded_left.ply")
    head.export(subject / "pinna_left_crop.ply")
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["data_root"] = str(tmp_path / "data")
    config["hrtf"].update(enabled=True, solver="numcalc", numcalc=str(numcalc), polar_step_deg=15.0,
                          frequencies_hz={"min": 500.0, "max": 1000.0, "step": 500.0},
                          frequency_bands={"variants": ["reference"],
                                           "bands": [{"up_to_hz": 600.0, "edges_mm": [25.0, 25.0, 25.0, 25.0]}]})
    (work / "config" / "banded.yaml").write_text(yaml.safe_dump(config))
    rules = ["--allowed-rules", "band_head", "export_band_project", "export_project", "solve_numcalc_step",
             "collect_sofa"]
    done = subprocess.run([sys.executable, "-m", "snakemake", "results/S1/hrtf/reference/HRIR.sofa", *rules, "--cores",
                           "2", "--configfile", "config/banded.yaml"], cwd=work, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    base = work / "results/S1/hrtf/reference"
    band = json.loads((base / "band_1/sources.json").read_text())
    assert band["elements"] < band["elements_full"]  # a coarser mesh for the 500 Hz step
    for source in (1, 2):
        full_folder, band_folder = base / f"project/NumCalc/source_{source}", base / f"band_1/project/NumCalc/source_{source}"
        n_points = len(read_eval_grid_pressure(full_folder, 2))
        # step 1 (500 Hz) solved on the band mesh and merged; step 2 (1 kHz) on the full mesh only
        np.testing.assert_array_equal(read_eval_grid_pressure(full_folder, 1, n_points),
                                      read_eval_grid_pressure(band_folder, 1, n_points))
        assert not (band_folder / "be.out" / "be.2").exists()
        statuses = json.loads((base / f"steps/source_{source}/steps_1-1.json").read_text())["steps"]
        assert statuses[0]["step"] == 1
    hrir = sofar.read_sofa(str(base / "HRIR.sofa"), verify=True)
    assert hrir.Data_IR.shape[1] == 2
