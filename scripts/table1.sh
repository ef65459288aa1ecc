#!/usr/bin/env bash
# The main job: the paper's Table 1 dialogue through the real multi-process ROS 2 node
# graph, once per forgetting policy, printed side by side and checked against the paper, with
# each policy's alignment with the human (and its gain over policy none) and one WM timeline
# PNG per policy in $FSREG_OUT (default: out/ in the repository, git-ignored); it prints their paths.
# Each policy's run is a graph of its own (fsreg-graph gives it a namespace and an identity), so
# jobs on one ROS domain do not mix; the exit status is non-zero when a description differs from
# the paper's or when any output would be built from incomplete data (an answer or WM event
# missing or from another graph: the run fails with one line instead of printing a table).
# Usage: scripts/table1.sh [SCENARIO.yaml] [extra fsreg-graph options]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/venv.sh"
. "$root/scripts/rosenv.sh"
scenario="${1:-$root/scenarios/guess_who_table1.yaml}"
shift || true
exec "$root/.venv/bin/fsreg-graph" "$scenario" \
  --compare-policies decay,displacement,none --expect "$root/config/paper_table1.yaml" \
  --plot-dir "${FSREG_OUT:-$root/out}" "$@"
