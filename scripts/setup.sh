#!/usr/bin/env bash
# Create .venv (Python 3.11: bpy wheels exist only for it) and install the project into it.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3.11}"
command -v "$PYTHON" >/dev/null 2>&1 || PYTHON=python3
"$PYTHON" - <<'PY'
import sys
if sys.version_info[:2] != (3, 11):
    sys.exit(f"Python 3.11 is required (bpy is built for it); found {sys.version.split()[0]}. "
             "Set PYTHON=/path/to/python3.11 and run again.")
PY
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test,slurm,docs]"
