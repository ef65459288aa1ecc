#!/usr/bin/env bash
# Regenerate every figure of README.md and docs/research.md: each block between
# "<!-- figure NAME -->" and "<!-- /figure -->" is rewritten from the one command it shows
# (fsreg-eval, fsreg-sim, fsreg-graph, fsreg-sweep at their documented size; outputs and PNGs in out/figures/).
# Creates or refreshes .venv first, like the other scripts.
#
# Usage: scripts/figures.sh [TUNA_DIR] [--tangrams DIR] [--check] [--only NAME ...]
#   TUNA_DIR   the TUNA corpus (its trial XML files); default: $FSREG_TUNA_DIR. Not shipped (licence).
#   --tangrams the tangram games of Hawkins, Frank & Goodman (2020), the directory holding
#              tangramsSequential.csv; default: $FSREG_TANGRAMS_DIR. Not shipped (no licence file).
#   --check    re-run every command and compare with the documents instead of rewriting them
#              (exit 1 and a diff if any block differs; the "Run time:" lines are not compared).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/venv.sh"
. "$root/scripts/rosenv.sh"  # the main job's figure (table1-graph) runs the node graph: loopback, a ROS domain
args=()
if [ $# -gt 0 ] && [ "${1#-}" = "$1" ]; then
  args+=(--tuna "$1")
  shift
fi
cd "$root"
exec "$root/.venv/bin/python" -m fsreg_ros.tools.figures "${args[@]}" "$@"
