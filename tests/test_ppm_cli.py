"""The `ppm` command line, run as a user would (separate processes, real bpy and pyvista)."""
import subprocess
import sys

import numpy as np
import trimesh

from ppm.parameters import PinnaParameters, parameter_specs

PPM = [sys.executable, "-m", "ppm.cli"]


def _ppm(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(PPM + list(args), capture_output=True, text=True, timeout=300)


def test_pose_writes_every_format(tmp_path):
    params = PinnaParameters.from_dict({"Shape_key_Ear_canal-Diameter": 1.0, "Rotation_Lobulus-End_Y": 5.0})
    params.write(tmp_path / "in.json")
    outs = [tmp_path / f"posed{s}" for s in (".ply", ".stl", ".obj", ".blend", ".csv")]
    done = _ppm("pose", *map(str, outs), "--parameters", str(tmp_path / "in.json"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert all(p.stat().st_size > 0 for p in outs)
    assert PinnaParameters.read(tmp_path / "posed.csv") == params
    mesh = trimesh.load(tmp_path / "posed.ply", process=False)
    assert mesh.vertices.shape[1] == 3 and np.isfinite(mesh.vertices).all()


def test_bad_parameter_file_gives_a_clear_error_and_no_output(tmp_path):
    (tmp_path / "bad.csv").write_text("name,value\nLocation_Tragus-Strat_X,1.0\n")
    done = _ppm("pose", str(tmp_path / "out.ply"), "--parameters", str(tmp_path / "bad.csv"))
    assert done.returncode == 2
    assert "bad.csv" in done.stderr and "did you mean 'Location_Tragus-Start_X'" in done.stderr
    assert not (tmp_path / "out.ply").exists()
    (tmp_path / "far.csv").write_text("name,value\nScale_Lobulus-Bendy,3.0\n")
    done = _ppm("pose", str(tmp_path / "out.ply"), "--parameters", str(tmp_path / "far.csv"))
    assert done.returncode == 2 and "out of range" in done.stderr
    clipped = _ppm("pose", str(tmp_path / "out.csv"), "--parameters", str(tmp_path / "far.csv"), "--clip")
    assert clipped.returncode == 0, clipped.stderr[-2000:]
    upper = {spec.name: spec.upper for spec in parameter_specs()}["Scale_Lobulus-Bendy"]
    assert PinnaParameters.read(tmp_path / "out.csv")["Scale_Lobulus-Bendy"] == upper  # clamped to its bound


def test_render_makes_a_png(tmp_path):
    done = _ppm("render", str(tmp_path / "ppm.png"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "ppm.png").read_bytes()[:4] == b"\x89PNG"


def test_missing_template_folder_is_named(tmp_path):
    done = _ppm("pose", str(tmp_path / "x.ply"), "--template", str(tmp_path / "nothing"))
    assert done.returncode == 2
    assert "nothing" in done.stderr and "build one with `ppm build-template`" in done.stderr
