#!/usr/bin/env bash
# Set up the environment, build the documentation and run the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The documentation site, warnings as errors (a broken link, a missing page or an unresolved API reference fails).
DISABLE_MKDOCS_2_WARNING=true NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict --quiet
.venv/bin/python -m pytest -q --durations=20 tests "$@"
