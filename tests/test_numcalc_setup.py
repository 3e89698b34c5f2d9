"""NumCalc set-up: the cluster tree NumCalc builds (its rule, replicated), the level-0 cluster size the
exporter writes, `m2h doctor`, and scripts/install_numcalc.sh (with a stand-in source tree; the real
Mesh2HRTF sources are the user's download)."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest
import trimesh

from mesh2hrtf_io import Mesh2HrtfIoError, sphere_grid, write_project
from mesh2hrtf_io.clusters import (MIN_CLUSTER_ELEMENTS, chosen_cluster_size_m, cluster_tree, fine_cluster_size_m,
                                   planned_cluster_tree)
from mesh2hrtf_io.doctor import doctor, numcalc_status
from mesh2hrtf_io.ear_canal import ear_canal_elements

ROOT = Path(__file__).resolve().parents[1]


def test_numcalc_default_tree_depends_on_the_element_count_alone():
    """NumCalc's default: 2 levels below ~32,400 elements, 3 above, whatever the element size."""
    for length in (0.001, 0.0023, 0.005):
        assert cluster_tree(27744, length).levels == 2
        assert cluster_tree(30562, length).levels == 2
        assert cluster_tree(34500, length).levels == 3
        assert cluster_tree(38750, length).levels == 3
    small, large = cluster_tree(30562, 0.00226), cluster_tree(38750, 0.00201)
    assert small.finest_m / small.element_length_m == pytest.approx(6.97, abs=0.05)
    assert large.finest_m / large.element_length_m == pytest.approx(3.70, abs=0.05)


def test_the_chosen_size_gives_three_levels_with_the_smallest_finest_clusters():
    length = 0.00226
    size = chosen_cluster_size_m(30562, length)
    tree = cluster_tree(30562, length, size)
    assert tree.levels == 3
    assert tree.finest_m == pytest.approx(MIN_CLUSTER_ELEMENTS * length * 2 ** -0.45, rel=1e-6)
    assert cluster_tree(30562, length, fine_cluster_size_m(30562, length, 4)).levels == 4
    assert chosen_cluster_size_m(5000, length) == 0.0  # small meshes keep NumCalc's default
    with pytest.raises(ValueError, match="below NumCalc's smallest allowed"):
        cluster_tree(30562, length, 0.010)


def _head(subdivisions: int) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=87.5)


def test_the_exporter_writes_the_level0_size_into_nc_inp(tmp_path):
    head = _head(5)  # 20,480 elements
    ears = {"left": ear_canal_elements(head, "left")}
    grid = sphere_grid("Sphere", trimesh.creation.icosphere(subdivisions=1, radius=1.2).vertices)
    write_project(tmp_path / "auto", head.vertices, head.faces, ears, [grid], [1000.0], source_type="Left ear")
    tree = json.loads((tmp_path / "auto" / "numcalc_clusters.json").read_text())
    assert tree["levels"] == 3 and tree["written_m"] > 0
    nc_inp = (tmp_path / "auto" / "NumCalc" / "source_1" / "NC.inp").read_text().split("\n")
    line = nc_inp[nc_inp.index("## 2. Main Parameters II") + 1]
    assert line == f"0 0 0 {tree['written_m']:.4e} 0 0 0"
    expected = planned_cluster_tree(head.vertices / 1000, head.faces)
    assert tree["written_m"] == pytest.approx(round(expected.written_m, 4))
    write_project(tmp_path / "default", head.vertices, head.faces, ears, [grid], [1000.0], source_type="Left ear",
                  numcalc_cluster_size=0.0)
    nc_inp = (tmp_path / "default" / "NumCalc" / "source_1" / "NC.inp").read_text().split("\n")
    assert nc_inp[nc_inp.index("## 2. Main Parameters II") + 1] == "0 0 0 0.0000e+00 0 0 0"
    with pytest.raises(Mesh2HrtfIoError, match="below NumCalc's smallest allowed"):
        write_project(tmp_path / "tiny", head.vertices, head.faces, ears, [grid], [1000.0], source_type="Left ear",
                      numcalc_cluster_size=0.001)
    with pytest.raises(Mesh2HrtfIoError, match="'auto' or a size in metres"):
        write_project(tmp_path / "bad", head.vertices, head.faces, ears, [grid], [1000.0], source_type="Left ear",
                      numcalc_cluster_size=float("nan"))
    assert not (tmp_path / "tiny").exists() and not (tmp_path / "bad").exists()


def _fake_numcalc(folder: Path, knows_estimate_ram: bool) -> Path:
    path = folder / "NumCalc"
    text = "-estimate_ram : estimation the RAM consumption" if knows_estimate_ram else "-istart int"
    path.write_text(f"#!/bin/sh\necho '{text}'\n")
    path.chmod(0o755)
    return path


def test_doctor_says_which_solver_is_usable_and_why(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setattr("mesh2hrtf_io.numcalc.venv_numcalc", lambda: tmp_path / "nowhere" / "NumCalc")
    report = doctor()
    assert not report["numcalc"]["usable"] and "install_numcalc.sh" in report["numcalc"]["why"]
    assert report["embedded"]["usable"] and "embedded" in report["advice"]
    good = _fake_numcalc(tmp_path, True)
    assert numcalc_status(str(good))["usable"]
    (tmp_path / "old").mkdir()
    old = _fake_numcalc(tmp_path / "old", False)
    status = numcalc_status(str(old))
    assert not status["usable"] and "not NumCalc from Mesh2HRTF 1.2.x" in status["why"]
    monkeypatch.setattr("mesh2hrtf_io.numcalc.venv_numcalc", lambda: good)
    assert doctor()["numcalc"]["path"] == str(good)  # found in the environment without PATH


def _install(argument: str, prefix: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMCALC_PREFIX=str(prefix))
    return subprocess.run(["bash", str(ROOT / "scripts" / "install_numcalc.sh"), argument], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def test_install_script_builds_with_the_checkouts_own_makefile(tmp_path):
    done = _install(str(tmp_path / "missing"), tmp_path / "bin")
    assert done.returncode == 2 and "holds no NumCalc sources" in done.stderr
    assert not (tmp_path / "bin" / "NumCalc").exists()
    # a stand-in checkout with Mesh2HRTF's layout and Makefile convention (binary into ../bin/NumCalc)
    source = tmp_path / "Mesh2HRTF" / "mesh2hrtf" / "NumCalc" / "src"
    source.mkdir(parents=True)
    (source / "NC_Main.cpp").write_text('#include <cstdio>\nint main(){std::puts("-estimate_ram : estimation");}\n')
    (source / "NC_Macros.h").write_text("// stand-in\n")
    (source / "Makefile").write_text("all:\n\tg++ -O2 NC_Main.cpp -o ../bin/NumCalc\n")
    done = _install(str(tmp_path / "Mesh2HRTF"), tmp_path / "bin")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "bin" / "NumCalc").is_file() and '"usable": true' in done.stdout
    assert not (source.parent / "bin").exists()  # built in a temporary copy: the checkout is untouched
    broken = tmp_path / "Broken" / "mesh2hrtf" / "NumCalc" / "src"
    broken.mkdir(parents=True)
    (broken / "NC_Main.cpp").write_text("not C++\n")
    (broken / "Makefile").write_text("all:\n\tg++ NC_Main.cpp -o ../bin/NumCalc\n")
    done = _install(str(tmp_path / "Broken"), tmp_path / "bin2")
    assert done.returncode == 1 and "the build failed" in done.stderr and not (tmp_path / "bin2" / "NumCalc").exists()
