#!/usr/bin/env bash
# Stress check of issue 20: the graph equals the simulator every time, not almost every time.
#
# Usage: scripts/stress_graph.sh [N] [SCENARIO.yaml]     (default N=200, the Table 1 scenario)
#
# Runs the main job's graph (fsreg-graph SCENARIO --compare-policies decay,displacement,none
# --expect config/paper_table1.yaml --json --trace-dir DIR) until N runs are compared, taking
# turns between three conditions: alone; two at once in different namespaces (two runs);
# beside a CPU hog (one busy loop per core, each ended when the run ends and bounded by
# `timeout` in any case). Each run's JSON and WM traces are compared byte for byte with
# fsreg-sim's (computed once), and its exit code with fsreg-sim's. It prints one line per run
# and a summary:
#   stress_graph: 200/200 runs identical to fsreg-sim (alone 67/67, two at once 66/66, beside a CPU hog 67/67)
# A run that differs keeps its output in $FSREG_STRESS_KEEP (default: a directory it names);
# a run that fails (exit != fsreg-sim's: e.g. the player refusing an incomplete event
# stream) is counted apart. Exit status: 0 if every run was identical, 1 otherwise, 2 on bad usage.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
total="${1:-200}"
scenario="${2:-$root/scenarios/guess_who_table1.yaml}"
if ! [[ "$total" =~ ^[1-9][0-9]*$ ]]; then
  echo "stress_graph: error: N must be a whole number >= 1, got '$total'" >&2
  exit 2
fi
"$root/scripts/venv.sh"
. "$root/scripts/rosenv.sh"
bin="$root/.venv/bin"
args=(--compare-policies decay,displacement,none --expect "$root/config/paper_table1.yaml" --json)
work="$(mktemp -d "${TMPDIR:-/tmp}/fsreg-stress-XXXXXX")"
keep="${FSREG_STRESS_KEEP:-$work/kept}"
hogs=()
stop_hogs() {
  local pid
  for pid in "${hogs[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${hogs[@]}"; do wait "$pid" 2>/dev/null || true; done
  hogs=()
}
cleanup() { stop_hogs; rm -rf "$work/run"-*; }
trap cleanup EXIT
trap 'exit 130' INT TERM

# The reference: fsreg-sim with the same arguments.
mkdir -p "$work/sim"
set +e
"$bin/fsreg-sim" "$scenario" "${args[@]}" --trace-dir "$work/sim" > "$work/sim.json" 2> "$work/sim.err"
sim_code=$?
set -e

declare -A same=([alone]=0 [pair]=0 [hog]=0) runs=([alone]=0 [pair]=0 [hog]=0)
failed=0 differ=0 count=0 started=$SECONDS

# compare MODE DIR CODE: one run's outputs against the reference; prints one line.
compare() {
  local mode="$1" dir="$2" code="$3" verdict
  runs[$mode]=$((runs[$mode] + 1))
  count=$((count + 1))
  if [ "$code" != "$sim_code" ]; then
    verdict="FAILED (exit $code): $(tail -n 1 "$dir/err" 2>/dev/null | cut -c1-200)"
    failed=$((failed + 1))
  elif cmp -s "$dir/out.json" "$work/sim.json" && diff -rq "$dir/trace" "$work/sim" > /dev/null; then
    verdict="identical"
    same[$mode]=$((same[$mode] + 1))
  else
    mkdir -p "$keep"
    cp -r "$dir" "$keep/run-$count-$mode"
    verdict="DIFFERS from fsreg-sim (kept in $keep/run-$count-$mode)"
    differ=$((differ + 1))
  fi
  echo "run $count/$total ($mode): $verdict"
}

# graph DIR [--namespace NS]: one main-job graph run into DIR; its exit code in DIR/code.
graph() {
  local dir="$1"; shift
  mkdir -p "$dir/trace"
  set +e
  "$bin/fsreg-graph" "$scenario" "${args[@]}" --trace-dir "$dir/trace" "$@" > "$dir/out.json" 2> "$dir/err"
  echo $? > "$dir/code"
  set -e
}

turn=0
while [ "$count" -lt "$total" ]; do
  run="$work/run-$turn"
  case $((turn % 3)) in
    0)
      graph "$run-a"
      compare alone "$run-a" "$(cat "$run-a/code")"
      ;;
    1)
      if [ $((total - count)) -ge 2 ]; then
        ns="stress_${$}_${turn}"
        graph "$run-a" --namespace "${ns}_a" &
        first=$!
        graph "$run-b" --namespace "${ns}_b" &
        second=$!
        wait "$first" "$second" || true
        compare pair "$run-a" "$(cat "$run-a/code")"
        compare pair "$run-b" "$(cat "$run-b/code")"
      fi
      ;;
    2)
      for _ in $(seq "$(nproc)"); do
        timeout 600 "$bin/python" -c "while True: pass" &
        hogs+=($!)
      done
      graph "$run-a"
      stop_hogs
      compare hog "$run-a" "$(cat "$run-a/code")"
      ;;
  esac
  rm -rf "$run"-*
  turn=$((turn + 1))
done

identical=$((same[alone] + same[pair] + same[hog]))
echo "stress_graph: $identical/$total runs identical to fsreg-sim (alone ${same[alone]}/${runs[alone]}," \
  "two at once ${same[pair]}/${runs[pair]}, beside a CPU hog ${same[hog]}/${runs[hog]}); $differ differ," \
  "$failed failed; $((SECONDS - started)) s"
[ "$identical" -eq "$total" ]
