"""Exploration for "a mesh per frequency band" (issue 40): how much NumCalc time a coarser mesh saves on the low
steps of a head whose 40 full-mesh steps are committed, and how far its pressures move.

For one head (default P143 ``original``) the exported full-mesh project is remeshed coarser for one band of
frequencies (default the steps up to 3 kHz) by :func:`stitching.frequency_bands.band_mesh`: the faces within
``--keep-mm`` of the ear-canal source are kept as they are (the source keeps its element area and position), the
rest is remeshed by distance to the pinna (the dataset's pinna crop) with the band's edge lengths, slivers repaired. The band's steps are solved by NumCalc and compared with the committed
full-mesh steps of the same frequencies: magnitude difference over the 793 directions (median, p95, max dB) and
NumCalc CPU seconds. Results: benchmarks/results/band_meshes/<subject>_<head>_up_to_<Hz>_edges_<mm>.json.

This measures one band at a time to choose band limits and edge lengths; the workflow's hrtf.frequency_bands (config/config.yaml) takes the set judged best. A band's steps may come from a wider band's result on the same mesh (the mesh depends on the edges only).

Run: .venv/bin/python benchmarks/band_meshes.py [--subject P143] [--head original] [--from-hz 0] [--up-to-hz 3000]
     [--edges 3,5,8,12] [--numcalc PATH]
Last line: JSON with band_steps, elements_full, elements_band, cpu_seconds_full, cpu_seconds_band, ratio,
max_median_db, max_p95_db. The band's pressures are kept beside its JSON (.npz).

Judge banded heads (no solve; the bands of --band-set must have been solved):
     .venv/bin/python benchmarks/band_meshes.py --judge P143/original,P143/ppm --band-set "0-3000:3,5,8,12;..."
Last line: JSON with cpu_hours_full, cpu_hours_banded, ratio (the worst head's), max_dqe_pp, max_dpe_deg (banded
against full, QE/PE by the paper's protocol with the full-mesh original as reference), max_p95_db.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

KEPT = ROOT / "benchmarks" / "results" / "band_meshes"
DISTANCES_MM = (12.0, 30.0, 60.0, None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--head", default="original")
    parser.add_argument("--from-hz", type=float, default=0.0, help="the band's lowest frequency (exclusive)")
    parser.add_argument("--up-to-hz", type=float, default=3000.0)
    parser.add_argument("--edges", default="3,5,8,12", help="edge lengths (mm) within 12, 30, 60 mm of the pinna "
                        "and beyond")
    parser.add_argument("--keep-mm", type=float, default=5.0)
    parser.add_argument("--numcalc", default=None)
    parser.add_argument("--judge", default=None, metavar="SUBJECT/HEAD,...",
                        help="solve nothing: judge these heads banded by the kept bands of --band-set against their "
                             "full-mesh solve (QE/PE by the paper's protocol, CPU hours)")
    parser.add_argument("--band-set", default="0-3000:3,5,8,12;3000-6000:2,3,5,8",
                        help="the bands of a banded head for --judge: FROM-UPTO:EDGES;... (Hz, mm)")
    args = parser.parse_args()
    if args.judge:
        judge_heads([tuple(h.split("/")) for h in args.judge.split(",")], args.band_set)
        return
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io import sphere_grid, write_project  # noqa: PLC0415
    from mesh2hrtf_io.numcalc import solve_project_numcalc  # noqa: PLC0415
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415
    from mesh2hrtf_io.results import read_eval_grid_pressure, step_status  # noqa: PLC0415
    from mesh2hrtf_io.step_store import solve_cpu_seconds  # noqa: PLC0415
    from stitching.frequency_bands import band_mesh, band_mesh_bands  # noqa: PLC0415

    full_dir = ROOT / f"results/{args.subject}/hrtf/{args.head}/project"
    if not full_dir.is_dir():
        raise SystemExit(f"{full_dir} is missing: export it first (snakemake --configfile config/paper_sonicom.yaml "
                         f"{full_dir.relative_to(ROOT)})")
    full = read_project(full_dir)
    steps = [i + 1 for i, f in enumerate(full.frequencies_hz) if args.from_hz < f <= args.up_to_hz]
    reference, cpu_full = _committed_steps(full_dir, args.subject, args.head, steps)
    edges = [float(e) for e in args.edges.split(",")]
    pinna = trimesh.load(ROOT.parent / "shared/data/sonicom" / args.subject / "pinna_left_crop.ply", process=False)
    start = time.perf_counter()
    bands = band_mesh_bands(DISTANCES_MM, edges)
    mesh, source = band_mesh(trimesh.Trimesh(full.vertices_m * 1000.0, full.faces, process=False),
                             full.sources[0].elements, np.asarray(pinna.vertices), bands, args.keep_mm,
                             f"{args.subject} {args.head}")
    print(f"{args.subject} {args.head}: {len(full.faces)} elements -> {len(mesh.faces)} for the band up to "
          f"{args.from_hz:.0f}-{args.up_to_hz:.0f} Hz ({len(steps)} steps; edges {edges} mm; remeshed in {time.perf_counter() - start:.0f} s)",
          flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        project = Path(tmp) / "band"
        write_project(project, mesh.vertices, mesh.faces, {"left": source},
                      [sphere_grid(full.grids[0].name, full.grids[0].points_m)], [full.frequencies_hz[s - 1] for s in steps],
                      source_type="Left ear", speed_of_sound_m_s=full.speed_of_sound_m_s,
                      density_kg_m3=full.density_kg_m3, title="band")
        solved = read_project(project)
        area_full = float(trimesh.Trimesh(full.vertices_m * 1000, full.faces).area_faces[full.sources[0].elements].sum())
        area_band = float(mesh.area_faces[source].sum())
        result = solve_project_numcalc(project, args.numcalc)
        band = [read_eval_grid_pressure(solved.sources[0].folder, i + 1, len(full.evaluation_points_m))
                for i in range(len(steps))]
        statuses = [step_status(solved.sources[0].folder, i + 1) or {} for i in range(len(steps))]
        shutil.rmtree(project)
    cpu_band = [solve_cpu_seconds(s) for s in statuses] if all(statuses) else list(result.get("seconds", []))
    rows = []
    for i, step in enumerate(steps):
        difference = np.abs(20 * np.log10(np.abs(band[i]) / np.abs(reference[i])))
        rows.append({"step": step, "frequency_hz": float(full.frequencies_hz[step - 1]),
                     "median_db": float(np.median(difference)), "p95_db": float(np.percentile(difference, 95)),
                     "max_db": float(difference.max()), "cpu_seconds_full": cpu_full[i],
                     "cpu_seconds_band": float(cpu_band[i]) if i < len(cpu_band) else None})
        print(f"  step {step} {rows[-1]['frequency_hz']:6.0f} Hz: |band - full| median {rows[-1]['median_db']:.3f} dB, "
              f"p95 {rows[-1]['p95_db']:.3f} dB, max {rows[-1]['max_db']:.2f} dB; NumCalc {cpu_full[i]:.0f} s full, "
              f"{rows[-1]['cpu_seconds_band'] or 0:.0f} s band")
    summary = {"subject": args.subject, "head": args.head, "from_hz": args.from_hz, "up_to_hz": args.up_to_hz, "edges_mm": edges,
               "keep_mm": args.keep_mm, "band_steps": len(steps), "elements_full": len(full.faces),
               "elements_band": len(mesh.faces), "source_area_full_mm2": round(area_full, 4),
               "source_area_band_mm2": round(area_band, 4), "cpu_seconds_full": round(sum(cpu_full), 1),
               "cpu_seconds_band": round(sum(r["cpu_seconds_band"] or 0 for r in rows), 1),
               "max_median_db": round(max(r["median_db"] for r in rows), 3),
               "max_p95_db": round(max(r["p95_db"] for r in rows), 3)}
    summary["ratio"] = round(summary["cpu_seconds_band"] / summary["cpu_seconds_full"], 3)
    KEPT.mkdir(parents=True, exist_ok=True)
    name = _result_name(args.subject, args.head, args.from_hz, args.up_to_hz, edges)
    (KEPT / f"{name}.json").write_text(json.dumps({**summary, "steps": rows}, indent=2) + "\n")
    # the band's pressures at the evaluation grid (steps, points), for judging a banded head by QE/PE (--judge)
    np.savez_compressed(KEPT / f"{name}.npz", steps=np.asarray(steps), pressure=np.asarray(band),
                        cpu_seconds=np.asarray([r["cpu_seconds_band"] or 0.0 for r in rows]))
    print(json.dumps(summary))


def _result_name(subject: str, head: str, from_hz: float, up_to_hz: float, edges_mm) -> str:
    """The file name (no suffix) of one band's results in benchmarks/results/band_meshes/."""
    band = f"{from_hz:.0f}_to_{up_to_hz:.0f}" if from_hz > 0 else f"up_to_{up_to_hz:.0f}"
    return f"{subject}_{head}_{band}_edges_{'-'.join(f'{float(e):g}' for e in edges_mm)}"


def _bands(band_set: str) -> list[tuple[float, float, list[str]]]:
    """The bands of ``band_set`` ("FROM-UPTO:EDGES;...", Hz and mm): (from, up to, edges)."""
    bands = []
    for band in band_set.split(";"):
        limits, edges = band.split(":")
        low, high = (float(x) for x in limits.split("-"))
        bands.append((low, high, edges.split(",")))
    return bands


def _kept_band(subject: str, head: str, low: float, high: float, edges) -> tuple[Path, list[int]]:
    """The kept result that solved the steps of ``low``-``high`` Hz on the band mesh of ``edges`` (the mesh
    depends on the edges only, so a wider band's result serves a narrower one) and those steps."""
    exact = KEPT / f"{_result_name(subject, head, low, high, edges)}.json"
    suffix = f"_edges_{'-'.join(f'{float(e):g}' for e in edges)}.json"
    candidates = [exact] + sorted(KEPT.glob(f"{subject}_{head}_*{suffix}"))
    for path in candidates:
        if not path.is_file():
            continue
        kept = json.loads(path.read_text())
        if kept["from_hz"] <= low and kept["up_to_hz"] >= high:
            return path, [row["step"] for row in kept["steps"] if low < row["frequency_hz"] <= high]
    raise SystemExit(f"{exact} is missing: solve the band {low:.0f}-{high:.0f} Hz with edges {edges} first (see --help)")


def _committed_steps(full_dir: Path, subject: str, head: str, steps) -> tuple[list[np.ndarray], list[float]]:
    """The committed full-mesh pressures (left ear, at the evaluation grid) and wall-clock seconds of ``steps`` of a
    head, checked against its exported project's fingerprint."""
    from mesh2hrtf_io.step_store import project_fingerprint, solve_seconds  # noqa: PLC0415

    store = ROOT / "evaluation" / "sonicom" / "steps" / subject / head / "source_1"
    fingerprint = project_fingerprint(full_dir, 1)
    pressures, seconds = [], []
    for step in steps:
        with np.load(store / f"step_{step:03d}.npz") as kept:
            if str(kept["fingerprint"]) != fingerprint:
                raise SystemExit(f"{store}: stored for another project")
            pressures.append(kept["pressure"])
            seconds.append(solve_seconds(json.loads(str(kept["status_json"]))))
    return pressures, seconds


def judge_heads(heads: list[tuple[str, str]], band_set: str) -> dict:
    """Each head with the kept bands of ``band_set`` in place of its full-mesh steps, against its full-mesh solve:
    QE/PE by the paper's protocol (the full-mesh ``original`` of the subject as reference and template, S at 8 %),
    NumCalc CPU hours of both (the full mesh's from the committed step statuses, the bands' from their solve)."""
    from mesh2hrtf_io.hrtf_job import collect_pressures  # noqa: PLC0415
    from mesh2hrtf_io.project_reader import read_project  # noqa: PLC0415
    from reporting.paper_protocol import paper_protocol  # noqa: PLC0415

    results = {}
    for subject, head in heads:
        full_dir = ROOT / f"results/{subject}/hrtf/{head}/project"
        if not full_dir.is_dir():
            raise SystemExit(f"{full_dir} is missing: export it first (snakemake --configfile config/paper_sonicom.yaml "
                             f"{full_dir.relative_to(ROOT)})")
        n_steps = len(read_project(full_dir).frequencies_hz)
        full, cpu_full = _committed_steps(full_dir, subject, head, range(1, n_steps + 1))
        banded, cpu_banded, p95 = list(full), list(cpu_full), []
        for low, high, edges in _bands(band_set):
            path, steps = _kept_band(subject, head, low, high, edges)
            with np.load(path.with_suffix(".npz")) as band:
                for step, pressure, seconds in zip(band["steps"], band["pressure"], band["cpu_seconds"]):
                    if int(step) in steps:
                        banded[int(step) - 1], cpu_banded[int(step) - 1] = pressure, float(seconds)
            p95.append(round(max(row["p95_db"] for row in json.loads(path.read_text())["steps"] if row["step"] in steps), 3))
        with tempfile.TemporaryDirectory() as tmp:
            sofa_full = collect_pressures(full_dir, full, Path(tmp) / "full")
            sofa_banded = collect_pressures(full_dir, banded, Path(tmp) / "banded")
            reference = (sofa_full if head == "original" else
                         ROOT / "evaluation" / "sonicom" / "sofa" / f"{subject}_original_left_HRTF.sofa")
            protocol = paper_protocol(reference, {"full": sofa_full, "banded": sofa_banded},
                                      ROOT.parent / "shared/data/sonicom" / subject / "hrir_mesh2hrtf_48k.sofa")
        row = {"cpu_hours_full": round(sum(cpu_full) / 3600, 3), "cpu_hours_banded": round(sum(cpu_banded) / 3600, 3),
               "qe_full_percent": round(protocol["full"]["qe_percent"], 3),
               "qe_banded_percent": round(protocol["banded"]["qe_percent"], 3),
               "pe_full_deg": round(protocol["full"]["pe_deg"], 3), "pe_banded_deg": round(protocol["banded"]["pe_deg"], 3),
               "max_p95_db": max(p95)}
        row["ratio"] = round(row["cpu_hours_banded"] / row["cpu_hours_full"], 3)
        row["dqe_pp"] = round(row["qe_banded_percent"] - row["qe_full_percent"], 3)
        row["dpe_deg"] = round(row["pe_banded_deg"] - row["pe_full_deg"], 3)
        print(f"{subject} {head}: NumCalc {row['cpu_hours_full']:.2f} CPU h full, {row['cpu_hours_banded']:.2f} banded "
              f"(ratio {row['ratio']:.3f}); QE {row['qe_full_percent']:.2f} -> {row['qe_banded_percent']:.2f} % "
              f"({row['dqe_pp']:+.3f} pp), PE {row['pe_full_deg']:.2f} -> {row['pe_banded_deg']:.2f} deg "
              f"({row['dpe_deg']:+.3f} deg); worst band p95 {row['max_p95_db']:.2f} dB", flush=True)
        results[f"{subject}/{head}"] = row
    summary = {"band_set": band_set, "heads": results,
               "cpu_hours_full": round(sum(r["cpu_hours_full"] for r in results.values()), 3),
               "cpu_hours_banded": round(sum(r["cpu_hours_banded"] for r in results.values()), 3),
               "ratio": max(r["ratio"] for r in results.values()),
               "max_dqe_pp": max(abs(r["dqe_pp"]) for r in results.values()),
               "max_dpe_deg": max(abs(r["dpe_deg"]) for r in results.values()),
               "max_p95_db": max(r["max_p95_db"] for r in results.values())}
    (KEPT / "judged.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
