#!/usr/bin/env bash
# Set up the environment and run the main workflow on the bundled default data.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/snakemake --cores 2 "$@"
