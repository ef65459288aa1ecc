#!/usr/bin/env bash
# Run the whole test suite (core, nodes, in-process and multi-process graph, colcon
# build) in .venv, creating or refreshing it first. Extra arguments go to pytest.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/venv.sh"
. "$root/scripts/rosenv.sh"
cd "$root"
exec "$root/.venv/bin/python" -m pytest "$@"
