#!/usr/bin/env bash
# A recorder killed (SIGKILL) while the graph names it: how long later fsreg-ctl commands wait and warn.
# Starts fsreg-up (table 1) and fsreg-ctl record, kills the recorder, then times 12 describes (time since
# the kill, wall time, exit code, the start of stderr). Run from the repository with ROS_DOMAIN_ID set:
#   ROS_DOMAIN_ID=N scripts/probe_recorder_kill.sh
set -u
cd "$(dirname "$0")/.." && source scripts/rosenv.sh
work=$(mktemp -d)
ns=/kill_$$
.venv/bin/fsreg-up scenarios/guess_who_table1.yaml --namespace $ns --state-dir $work/state >/dev/null 2>&1 &
up=$!
.venv/bin/fsreg-ctl --namespace $ns status >/dev/null
.venv/bin/fsreg-ctl --namespace $ns record $work/bag >/dev/null 2>&1 &
rec=$!
.venv/bin/fsreg-ctl --namespace $ns describe face1 >/dev/null  # a few seconds: the graph discovers the recorder
.venv/bin/fsreg-ctl --namespace $ns describe face1 >/dev/null
kill -KILL $rec; k=$(date +%s.%N); echo killed
for i in $(seq 12); do
  s=$(date +%s.%N); .venv/bin/fsreg-ctl --namespace $ns describe face1 >/dev/null 2>$work/err; rc=$?; e=$(date +%s.%N)
  echo "t+$(echo "$s - $k" | bc | cut -c1-5) took $(echo "$e - $s" | bc | cut -c1-4) rc=$rc $(cut -c1-60 $work/err)"
done
kill -INT $up; wait $up
rm -rf "$work"
