"""Running the workflow as a user would, for the tests that run Snakemake: a clean copy of the workflow files and
one call of ``python -m snakemake`` in it."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def copy_workflow(tmp_path: Path) -> Path:
    """A clean copy of the workflow files (no results), as a user's checkout would be."""
    work = tmp_path / "project"
    for folder in ("workflow", "rules", "config"):
        shutil.copytree(ROOT / folder, work / folder)
    return work


def run_snakemake(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    """``snakemake ARGS`` in ``cwd``, output captured."""
    return subprocess.run(SNAKEMAKE + args, cwd=cwd, capture_output=True, text=True, timeout=timeout)
