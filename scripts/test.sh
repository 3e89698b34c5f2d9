#!/usr/bin/env bash
# Set up the environment, build the documentation and run the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The documentation site, warnings as errors (a broken link, a missing page or an unresolved API reference fails).
DISABLE_MKDOCS_2_WARNING=true NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict --quiet
if [ "$#" -gt 0 ]; then  # the tests asked for, in one process
    exec .venv/bin/python -m pytest -q --durations=20 "$@"
fi
# The suite on every core, one worker a test file (so a file's fixtures are made once); then the tests marked
# "alone" (the SLURM run, which checks its jobs' time limits) with the machine to themselves.
.venv/bin/python -m pytest -q --durations=20 -n "${PYTEST_WORKERS:-auto}" --dist loadfile -m "not alone" tests
.venv/bin/python -m pytest -q --durations=5 -m alone tests
