"""What a NumCalc run will cost, printed before it starts.

Per subject and head variant: the frequency steps to solve, how many of them the step store already holds
for this head (restored instead of solved: the fingerprint of the rebuilt head matches) and how many it holds
for an earlier head (a changed mesh or source: solved again), and the solver hours of the rest, estimated from
the seconds recorded with every stored step at the same step (the median over the heads solved so far: a
step's cost depends on its frequency, NumCalc iterating longest at the lowest and doing the most work at the
highest). NumCalc runs one single-threaded process per step, so the wall clock is about the solver hours
divided by the cores.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

STEP_FILE = re.compile(r"step_(\d+)\.npz$")


def measured_step_seconds(store_root: str | os.PathLike) -> dict[int, float]:
    """Step number (1-based) -> median solver seconds of that step over every stored head and source."""
    from mesh2hrtf_io.step_store import solve_seconds, stored_status  # noqa: PLC0415

    seconds: dict[int, list[float]] = {}
    root = Path(store_root)
    if not root.is_dir():
        return {}
    for path in sorted(root.glob("*/*/source_*/step_*.npz")):
        step = int(STEP_FILE.search(path.name).group(1))
        source = int(path.parent.name.split("_")[-1])
        value = solve_seconds(stored_status(path.parent.parent, source, step))
        if value > 0:
            seconds.setdefault(step, []).append(value)
    return {step: float(np.median(values)) for step, values in seconds.items()}


def _stored_fingerprints(folder: Path, n_steps: int) -> dict[int, tuple[str, str]]:
    """Step number -> (fingerprint of the head the stored step of one source was solved for, when it was saved
    (ISO UTC; "" for steps stored before the store kept it))."""
    prints = {}
    for step in range(1, n_steps + 1):
        path = folder / f"step_{step:03d}.npz"
        if path.is_file():
            with np.load(path) as stored:
                saved = str(stored["saved_utc"]) if "saved_utc" in stored.files else ""
                prints[step] = (str(stored["fingerprint"]), saved)
    return prints


def _latest_head(prints: dict[int, tuple[str, str]]) -> str | None:
    """The fingerprint most likely to be the head's before it is exported: that of the most recently saved
    step (the largest group where no step records when it was saved)."""
    if not prints:
        return None
    count = {}
    for fingerprint, _saved in prints.values():
        count[fingerprint] = count.get(fingerprint, 0) + 1
    return max(prints.values(), key=lambda item: (item[1], count[item[0]]))[0]


BUILT_HEADS = ("ppm", "own_pinna", "default_ppm", "ppm_detail", "ppm_hard", "ppm_detail_hard", "nricp_hard", "scan_hard", "personal", "scanned")  # heads the pipeline makes; kept in the store beside their steps


def plan_rows(store_root: str | os.PathLike | None, heads: list[tuple[str, str]], n_steps: int,
              sources: list[int], projects: dict[tuple[str, str], str | os.PathLike] | None = None,
              steps: dict[tuple[str, str], list[int]] | None = None) -> list[dict]:
    """One row per (subject, variant): whether the store keeps the head, steps in all, steps stored, how many of those belong to the head (the rest
    were solved for an earlier head and are solved again), steps to solve and their estimated solver hours (None
    where no stored step of that number has a recorded time).

    A stored step is restored only when its fingerprint matches the exported project. Where ``projects`` names
    an exported project of a head, its fingerprint decides (``checked``); before the export, the steps sharing
    the fingerprint of the most recently saved one are counted as the head's (a guess: the head may yet
    differ) and the rest as stale, except for a head the pipeline builds (BUILT_HEADS) that the store does not
    keep: a rebuild on another machine is not the same mesh, so its steps count as stale.

    A head solved on a mesh per frequency band comes as several parts: ``(subject, "ppm")`` for its full mesh and
    ``(subject, "ppm/band_1")``, ... for the band meshes (their store folders and projects below the variant's),
    each with its own ``steps`` (default: all ``n_steps``).
    """
    from mesh2hrtf_io.step_store import project_fingerprint, stored_head  # noqa: PLC0415

    measured = measured_step_seconds(store_root) if store_root else {}
    projects = projects or {}
    rows = []
    for subject, variant in heads:
        stored = usable = 0
        to_solve: list[int] = []
        project = projects.get((subject, variant))
        wanted = (steps or {}).get((subject, variant), list(range(1, n_steps + 1)))
        checked = project is not None and Path(project, "NumCalc").is_dir()
        kept = stored_head(Path(store_root) / subject / variant) if store_root else None
        unknown_head = variant in BUILT_HEADS and kept is None and not checked
        for source in sources:
            folder = Path(store_root) / subject / variant / f"source_{source}" if store_root else None
            prints = _stored_fingerprints(folder, n_steps) if folder is not None and folder.is_dir() else {}
            prints = {step: stored for step, stored in prints.items() if step in wanted}
            current = project_fingerprint(project, source) if checked else None if unknown_head else _latest_head(prints)
            stored += len(prints)
            for step in wanted:
                if step in prints and prints[step][0] == current:
                    usable += 1
                else:
                    to_solve.append(step)
        known = [measured[s] for s in to_solve if s in measured]
        hours = sum(known) / 3600.0 if len(known) == len(to_solve) else None
        rows.append({"subject": subject, "variant": variant, "head_stored": kept is not None,
                     "steps": len(wanted) * len(sources), "stored": stored,
                     "usable": usable, "stale": stored - usable, "checked": checked, "unknown_head": unknown_head,
                     "to_solve": len(to_solve), "solver_hours": hours})
    return rows


def plan_text(rows: list[dict], cores: int) -> str:
    """The plan as lines for the terminal, with the total and the wall clock on `cores` cores."""
    lines = ["NumCalc solve plan (steps kept in the step store are restored when the exported head is identical):"]
    for r in rows:
        estimate = f"~{r['solver_hours']:.1f} solver h" if r["solver_hours"] is not None else "no estimate yet"
        if r["stored"] == 0:
            kept = "0 stored"
        elif r["checked"]:
            kept = f"{r['usable']} stored for this head"
        else:
            kept = f"{r['usable']} stored, not yet checked against the rebuilt head"
        if r["stale"] and r.get("unknown_head"):
            kept = f"{r['stale']} stored for a head the store does not keep (a rebuild is not the same mesh), solved again"
        elif r["stale"]:
            kept += f"; {r['stale']} stored for an earlier head, solved again"
        head = ", head from the store" if r.get("head_stored") else ""
        lines.append(f"  {r['subject']} {r['variant']}: {r['to_solve']} of {r['steps']} steps to solve "
                     f"({kept}){head}, {estimate}")
    to_solve = sum(r["to_solve"] for r in rows)
    hours = [r["solver_hours"] for r in rows if r["to_solve"]]
    if to_solve == 0:
        lines.append("  nothing to solve: every step is stored")
    elif all(h is not None for h in hours):
        total = sum(hours)
        lines.append(f"  in all {to_solve} steps, ~{total:.1f} solver hours: ~{total / max(cores, 1):.1f} h on "
                     f"{cores} core(s) (estimated from the stored steps' recorded times at the same frequency step)")
    else:
        lines.append(f"  in all {to_solve} steps; no stored steps to estimate their time from yet "
                     "(each job's memory comes from NumCalc -estimate_ram)")
    return "\n".join(lines)


def embedded_plan_text(heads: list[tuple[str, str, str | None]], device: str, n_frequencies: int) -> str:
    """The embedded solver's plan: per head (subject, variant, its mesh in mm where it exists before the run) the
    vertices and the predicted seconds per frequency on ``device`` ('cuda': the GPU model measured on an H200; else
    the 2-core CPU model), and the total. Heads built during the run are estimated after their export."""
    import trimesh  # noqa: PLC0415

    from mesh2hrtf_io.bem import estimate_cost  # noqa: PLC0415

    backend = "cuda" if device == "cuda" else "numba"
    where = "on the GPU (model of an H200)" if backend == "cuda" else "on the CPU (2-core model)"
    lines = [f"Embedded solver plan, hrtf.embedded_device: {device}, {n_frequencies} frequencies per head, {where}:"]
    total, unknown = 0.0, 0
    for subject, variant, path in heads:
        if not path or not Path(path).is_file():
            unknown += 1
            lines.append(f"  {subject} {variant}: head built during the run, estimated after its export")
            continue
        mesh = trimesh.load(path, process=False, force="mesh")
        cost = estimate_cost(len(mesh.vertices), len(mesh.faces), 0, backend=backend)
        seconds = cost.seconds_per_frequency * n_frequencies
        total += seconds
        lines.append(f"  {subject} {variant}: {len(mesh.vertices)} vertices, ~{cost.seconds_per_frequency:.1f} s per "
                     f"frequency (all ears), ~{seconds / 60:.1f} min, {cost.memory_gb_per_frequency:.1f} GB")
    lines.append(f"  in all ~{total / 3600:.2f} h for the heads known now" + (f", {unknown} more after their export"
                                                                               if unknown else ""))
    return "\n".join(lines)
