"""What a NumCalc run will cost, printed before it starts.

Per subject and head variant: the frequency steps to solve, how many of them the step store already holds
(restored instead of solved when the rebuilt head is identical), and the solver hours of the rest, estimated
from the seconds recorded with every stored step at the same step (the median over the heads solved so far: a
step's cost depends on its frequency, NumCalc iterating longest at the lowest and doing the most work at the highest). NumCalc runs one single-threaded process per step, so the wall
clock is about the solver hours divided by the cores.
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


def plan_rows(store_root: str | os.PathLike | None, heads: list[tuple[str, str]], n_steps: int,
              sources: list[int]) -> list[dict]:
    """One row per (subject, variant): steps in all, steps stored, steps to solve and their estimated solver
    hours (None where no stored step of that number has a recorded time)."""
    measured = measured_step_seconds(store_root) if store_root else {}
    rows = []
    for subject, variant in heads:
        stored = 0
        to_solve: list[int] = []
        for source in sources:
            folder = Path(store_root) / subject / variant / f"source_{source}" if store_root else None
            for step in range(1, n_steps + 1):
                if folder is not None and (folder / f"step_{step:03d}.npz").is_file():
                    stored += 1
                else:
                    to_solve.append(step)
        known = [measured[s] for s in to_solve if s in measured]
        hours = sum(known) / 3600.0 if len(known) == len(to_solve) else None
        rows.append({"subject": subject, "variant": variant, "steps": n_steps * len(sources), "stored": stored,
                     "to_solve": len(to_solve), "solver_hours": hours})
    return rows


def plan_text(rows: list[dict], cores: int) -> str:
    """The plan as lines for the terminal, with the total and the wall clock on `cores` cores."""
    lines = ["NumCalc solve plan (steps kept in the step store are restored when the rebuilt head is identical):"]
    for r in rows:
        estimate = f"~{r['solver_hours']:.1f} solver h" if r["solver_hours"] is not None else "no estimate yet"
        lines.append(f"  {r['subject']} {r['variant']}: {r['to_solve']} of {r['steps']} steps to solve "
                     f"({r['stored']} stored), {estimate}")
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
