#!/usr/bin/env bash
# End to end: every `ros2 ...` command the docs promise (README, docs/deployment.md "The ros2 commands
# and their equivalents", config/*.yaml, launch/fsreg.launch.py), run for real with the ROS 2 CLI
# against graphs on this machine.  For a developer with a full ROS 2 Jazzy install (or the CLI beside
# the wheels: docs/testing.md, "The real ros2 CLI") and this package colcon-built and sourced:
#
#   colcon build --paths . --build-base /tmp/ws/build --install-base /tmp/ws/install
#   . /tmp/ws/install/setup.bash
#   ROS_DOMAIN_ID=<a free domain> scripts/check_ros2_cli.sh
#
# One line per check: `PASS: <command>` or `FAIL: <command> -- <what went wrong>`.  Exit 0 when every
# promise holds, 1 when one is broken, 2 when it cannot check (no `ros2` on PATH, fsreg_ros not
# installed, the ROS domain already has fsreg nodes, or another graph's nodes joined it during the
# run).  Loopback only (scripts/rosenv.sh); every node it starts is stopped at its end (SIGINT to the
# process group, as a terminal's Ctrl-C), and a ros2 daemon it started is stopped too.  Takes about
# 4 minutes.
set -u
me=check_ros2_cli
if ! command -v ros2 > /dev/null 2>&1; then
  echo "$me: error: no 'ros2' on PATH: source a ROS 2 Jazzy install and this package's colcon workspace first (docs/testing.md)" >&2
  exit 2
fi
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FSREG_PYTHON="${FSREG_PYTHON:-python3}" . "$repo/scripts/rosenv.sh" || exit 2
if ! prefix="$(ros2 pkg prefix fsreg_ros 2> /dev/null)"; then
  echo "$me: error: package 'fsreg_ros' not found by ros2: colcon build this checkout and source its install/setup.bash" >&2
  exit 2
fi
work="$(mktemp -d "${TMPDIR:-/tmp}/$me.XXXXXX")"
kb="$repo/scenarios/guess_who_table1.yaml"
failures=0
groups=()
daemon_was_running=0
ros2 daemon status 2> /dev/null | grep -q "is running" && daemon_was_running=1

pass() { echo "PASS: $1"; }
fail() { echo "FAIL: $1 -- $2"; failures=$((failures + 1)); }
# expect CMD_TEXT OUTPUT_FILE PATTERN...: PASS if every (extended) regex matches the output.
expect() {
  local what=$1 out=$2 pattern; shift 2
  for pattern in "$@"; do
    if ! grep -Eq -- "$pattern" "$out"; then
      fail "$what" "no match for /$pattern/ in: $(tr '\n' ' ' < "$out" | cut -c1-300)"
      return 1
    fi
  done
  pass "$what"
}
# run NAME CMD...: run a ros2 command (60 s at most); its stdout+stderr in $work/NAME.out, exit code in $rc.
# A node the ros2 daemon has not discovered yet ("Node not found", seen right after ready under load) is
# asked again, 5 times at most, 2 s apart: discovery time is not a promise.
run() {
  local name=$1 try; shift
  for try in 1 2 3 4 5; do
    timeout -s INT 60 "$@" > "$work/$name.out" 2>&1
    rc=$?
    grep -q "^Node not found" "$work/$name.out" || break
    sleep 2
  done
}
# start NAME CMD...: start CMD in a process group of its own (SIGINT at its default, as from a terminal).
start() {
  local name=$1; shift
  (cd "$repo" && exec setsid env --default-signal=INT "$@" > "$work/$name.log" 2>&1) &
  local pid=$! pgid=""
  for _ in $(seq 50); do  # until setsid has made it a group leader (2 s at most)
    pgid=$(ps -o pgid= -p $pid | tr -d ' ')
    [ "$pgid" = "$pid" ] && break
    sleep 0.04
  done
  eval "pgid_$name=$pgid"
  eval "pid_$name=$pid"
  groups+=("$(eval echo "\$pgid_$name")")
}
# stop NAME: SIGINT to its process group (a terminal's Ctrl-C); wait up to 10 s; sets $rc to its exit code.
stop() {
  local name=$1 pgid pid
  pgid=$(eval echo "\$pgid_$name"); pid=$(eval echo "\$pid_$name")
  kill -INT -- "-$pgid" 2> /dev/null
  for _ in $(seq 100); do
    pgrep -g "$pgid" > /dev/null || break
    sleep 0.1
  done
  if pgrep -g "$pgid" > /dev/null; then
    rc=124
    return
  fi
  wait "$pid" 2> /dev/null
  rc=$?
}
status() {  # status [NS]: the WM Manager's status reply (JSON text) in $work/status.out
  run status ros2 service call "${1:-}/wm_manager/status" diagnostic_msgs/srv/AddDiagnostics '{load_namespace: "{}"}'
}
# ready NS: wait (120 s at most: node start-up on a loaded machine) until NS's WM Manager answers with ready true
ready() {
  local deadline=$((SECONDS + 120))
  while [ $SECONDS -lt $deadline ]; do
    status "$1"
    grep -q '"ready":true' "$work/status.out" && return 0
    sleep 1
  done
  return 1
}
cleanup() {
  local g
  for g in "${groups[@]}"; do kill -INT -- "-$g" 2> /dev/null; done
  sleep 3
  for g in "${groups[@]}"; do kill -KILL -- "-$g" 2> /dev/null; done
  [ "$daemon_was_running" = 1 ] || ros2 daemon stop > /dev/null 2>&1
  rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 1' INT TERM

nodes="$(ros2 node list --no-daemon --spin-time 2 2> /dev/null | grep -E '(^|/)(wm_manager|reg|parser|reference_resolution|consultant_[a-z0-9_]+|dialogue_player)$' || true)"
if [ -n "$nodes" ]; then
  echo "$me: error: ROS domain $ROS_DOMAIN_ID already has fsreg nodes ($(echo $nodes)): set ROS_DOMAIN_ID to a free domain" >&2
  exit 2
fi

# --- the package as installed
installed="$prefix/share/fsreg_ros/launch/fsreg.launch.py"
if cmp -s "$installed" "$repo/launch/fsreg.launch.py"; then
  pass "the installed launch file is this checkout's ($installed)"
else
  fail "the installed launch file is this checkout's ($installed)" "it differs or is missing: colcon build again"
fi
run exes ros2 pkg executables fsreg_ros
expect "ros2 pkg executables fsreg_ros" "$work/exes.out" \
  "fsreg_ros parser$" "fsreg_ros reference_resolution$" "fsreg_ros consultant$" "fsreg_ros wm_manager$" \
  "fsreg_ros reg$" "fsreg_ros dialogue_player$"
run args ros2 launch fsreg_ros fsreg.launch.py --show-args
expect "ros2 launch fsreg_ros fsreg.launch.py --show-args" "$work/args.out" \
  $(for a in kb domains preset policy decay_period capacity global_capacity seed shared_capacity activation_decay \
      activation_threshold algorithm wm_order use_sim_time namespace lexicon state_dir fresh; do echo "'$a':"; done)

# --- bad launch arguments: one error line, no node started, a failing exit code
for bad in "" "kb:=$work/none.yaml" "kb:=$kb policy:=bogus" "kb:=$kb decay_period:=abc" "kb:=$kb fresh:=maybe" \
           "kb:=$kb domains:=nosuch" "kb:=$kb lexicon:=$work/none.yaml" "kb:=$kb algorithm:=foo" "kb:=$kb namespace:=bad-ns!"; do
  what="ros2 launch fsreg_ros fsreg.launch.py $bad (refused)"
  # shellcheck disable=SC2086
  run bad ros2 launch fsreg_ros fsreg.launch.py $bad
  errors=$(grep -c '^\[ERROR\]' "$work/bad.out")
  if [ "$rc" != 0 ] && [ "$rc" != 124 ] && [ "$errors" = 1 ] && ! grep -q "process started" "$work/bad.out"; then
    pass "$what"
  else
    fail "$what" "exit $rc, $errors error lines, $(grep -c 'process started' "$work/bad.out") nodes started: $(grep -v '^\[INFO\] \[launch\]' "$work/bad.out" | head -3 | tr '\n' ' ' | cut -c1-300)"
  fi
done

# an unknown preset: the one error line names the argument and the presets there are
what="ros2 launch fsreg_ros fsreg.launch.py kb:=$kb preset:=nonsense (refused in one line naming the presets)"
run bad ros2 launch fsreg_ros fsreg.launch.py "kb:=$kb" preset:=nonsense
errors=$(grep -c '^\[ERROR\]' "$work/bad.out")
if [ "$rc" != 0 ] && [ "$rc" != 124 ] && [ "$errors" = 1 ] && ! grep -q "process started" "$work/bad.out" \
   && grep -q "^\[ERROR\] .*launch argument preset:='nonsense': unknown preset 'nonsense' (known: paper, human-like)$" "$work/bad.out"; then
  pass "$what"
else
  fail "$what" "exit $rc, $errors error lines, $(grep -c 'process started' "$work/bad.out") nodes started: $(grep -v '^\[INFO\] \[launch\]' "$work/bad.out" | head -3 | tr '\n' ' ' | cut -c1-300)"
fi

# --- the docs' example (docs/deployment.md): the launch file on sim time, driven by hand
launch="ros2 launch fsreg_ros fsreg.launch.py kb:=$kb policy:=decay decay_period:=10.0 use_sim_time:=true fresh:=true state_dir:=$work/state"
# shellcheck disable=SC2086
start main $launch
if ready ""; then pass "$launch (ready)"; else fail "$launch (ready)" "no ready status within 120 s: $(tail -5 "$work/main.log" | tr '\n' ' ' | cut -c1-300)"; fi
run p1 ros2 param get /wm_manager policy
expect "ros2 param get /wm_manager policy" "$work/p1.out" "String value is: decay$"
run p2 ros2 param get /reg algorithm
expect "ros2 param get /reg algorithm" "$work/p2.out" "String value is: auto$"
run p3 ros2 param set /wm_manager policy displacement
run p3b ros2 param get /wm_manager policy
status ""
cat "$work/p3b.out" "$work/status.out" >> "$work/p3.out"
expect "ros2 param set /wm_manager policy displacement" "$work/p3.out" "^Set parameter successful$" \
  "String value is: displacement$" '"running":\{"faces":\{"policy":"displacement"'
# refusals: one line, nothing changed
refused() {  # refused COMMAND_WORDS... -- PARAMETER EXPECTED_GET PATTERN
  local words=() param expected pattern
  while [ "$1" != "--" ]; do words+=("$1"); shift; done
  param=$2 expected=$3 pattern=$4
  run refused "${words[@]}"
  run after ros2 param get /wm_manager "$param"
  if [ "$(grep -c . "$work/refused.out")" = 1 ] && grep -Eq -- "$pattern" "$work/refused.out" && grep -q "value is: $expected\$" "$work/after.out"; then
    pass "${words[*]} (refused in one line, nothing changed)"
  else
    fail "${words[*]} (refused in one line, nothing changed)" "$(cat "$work/refused.out" "$work/after.out" | tr '\n' ' ' | cut -c1-300)"
  fi
}
refused ros2 param set /wm_manager use_sim_time false -- use_sim_time True "read-only parameter: use_sim_time"
refused ros2 param set /wm_manager capacity 0 -- capacity 2 "out of range. Min: 1, Max: 10000"
refused ros2 param set /wm_manager policy bogus -- policy displacement "unknown forgetting rule 'bogus'"
run fp ros2 param set /wm_manager faces.policy none
refused ros2 param set /wm_manager policy decay -- policy displacement "set faces.policy instead, or faces.policy='' to inherit"
run fp2 ros2 param set /wm_manager faces.policy "''"
run fp3 ros2 param get /wm_manager faces.policy
cat "$work/fp.out" "$work/fp2.out" "$work/fp3.out" > "$work/fp_all.out"
expect "ros2 param set /wm_manager faces.policy none, then faces.policy ''" "$work/fp_all.out" \
  "^Set parameter successful$" "String value is: $"
run d1 ros2 param describe /wm_manager capacity
expect "ros2 param describe /wm_manager capacity" "$work/d1.out" "Min value: 1$" "Max value: 10000$"
run d2 ros2 param dump /wm_manager
expect "ros2 param dump /wm_manager" "$work/d2.out" "^/wm_manager:$" "^  ros__parameters:$" "^    policy: displacement$" \
  "^    use_sim_time: true$"
run c1 ros2 topic pub --once -w 5 /clock rosgraph_msgs/msg/Clock '{clock: {sec: 30}}'
status ""
cat "$work/status.out" >> "$work/c1.out"
expect "ros2 topic pub --once -w 5 /clock rosgraph_msgs/msg/Clock '{clock: {sec: 30}}'" "$work/c1.out" '"time":30\.0'
start echo_expr ros2 topic echo --full-length /reg/expression
start echo_rr ros2 topic echo --full-length /rr/result
sleep 3
request='{data: "{\"id\": \"readme-1\", \"target\": \"face1\"}"}'
run r1 ros2 topic pub --once -w 1 /reg/request std_msgs/String "$request"
utterance='{data: "{\"id\": \"check-2\", \"text\": \"a man with light hair, glasses and a lab coat\"}"}'
run h1 ros2 topic pub --once -w 1 /dialogue/human std_msgs/String "$utterance"
assertion='{data: "{\"id\": \"readme-3\", \"domain\": \"faces\", \"entity\": \"face17\", \"properties\": {\"female\": 1.0}}"}'
run a1 ros2 topic pub --once -w 2 /ltm/assert std_msgs/String "$assertion"
run r2 ros2 topic pub --once -w 1 /reg/request std_msgs/String '{data: "{\"id\": \"check-4\", \"target\": \"face17\"}"}'
sleep 3
expect "ros2 topic pub --once -w 1 /reg/request std_msgs/String '$request' (+ ros2 topic echo /reg/expression)" \
  "$work/echo_expr.log" '"id":"readme-1"[^}]*"target":"face1"[^}]*"description":\["'
expect "ros2 topic pub --once -w 1 /dialogue/human std_msgs/String '$utterance' (+ ros2 topic echo /rr/result)" \
  "$work/echo_rr.log" '"id":"check-2".*"status":"resolved","resolved":"face1"'
expect "ros2 topic pub --once -w 2 /ltm/assert std_msgs/String '$assertion' (face17 described after)" \
  "$work/echo_expr.log" '"id":"check-4"[^}]*"target":"face17"[^}]*"description":\["female"'
run w1 ros2 topic echo --once --full-length /wm/state
expect "ros2 topic echo --once /wm/state" "$work/w1.out" '"domain":"faces"' '"queues":'
run g1 ros2 topic echo --once /diagnostics
expect "ros2 topic echo --once /diagnostics" "$work/g1.out" "name: 'fsreg: /"
status ""
expect "ros2 service call /wm_manager/status diagnostic_msgs/srv/AddDiagnostics '{load_namespace: \"{}\"}'" \
  "$work/status.out" "success=True" '"ready":true' '"graph":'
# another graph joining the domain mid-run (a test run's second worker) answers in our place: say so, exit 2
intruders="$(ros2 node list --no-daemon --spin-time 2 2> /dev/null | sort | uniq -d | tr '\n' ' ')"
stop echo_expr; stop echo_rr
stop main
if [ "$rc" = 0 ] && [ "$(grep -c 'process has finished cleanly' "$work/main.log")" = 5 ] && ! grep -q Traceback "$work/main.log"; then
  pass "Ctrl-C on $launch (every node exits 0)"
else
  fail "Ctrl-C on $launch (every node exits 0)" "exit $rc: $(grep -E 'finished|died|Traceback' "$work/main.log" | tr '\n' ' ' | cut -c1-300)"
fi

# --- the state is kept: the same launch without fresh restores face17's runtime fact
again="ros2 launch fsreg_ros fsreg.launch.py kb:=$kb use_sim_time:=true state_dir:=$work/state"
# shellcheck disable=SC2086
start again $again
if ready ""; then
  expect "$again (restores the runtime fact)" "$work/status.out" '"restored":\{"faces":\{"fresh":false,"runtime_entities":1,"runtime_facts":1'
else
  fail "$again (restores the runtime fact)" "no ready status within 120 s: $(tail -5 "$work/again.log" | tr '\n' ' ' | cut -c1-300)"
fi
stop again

# --- a preset (README, docs/deployment.md): people's rule, episodes k = 1 and REG's strength order
preset="ros2 launch fsreg_ros fsreg.launch.py kb:=$kb preset:=human-like use_sim_time:=true fresh:=true state_dir:=$work/state_preset"
# shellcheck disable=SC2086
start preset $preset
if ready ""; then pass "$preset (ready)"; else fail "$preset (ready)" "no ready status within 120 s: $(tail -5 "$work/preset.log" | tr '\n' ' ' | cut -c1-300)"; fi
run h1 ros2 param get /wm_manager policy
run h2 ros2 param get /wm_manager episode_window
run h3 ros2 param get /reg wm_order
cat "$work/h1.out" "$work/h2.out" "$work/h3.out" > "$work/h.out"
status ""
expect "ros2 param get /wm_manager policy, episode_window; /reg wm_order (preset:=human-like)" "$work/h.out" \
  "^String value is: episodes$" "^Integer value is: 1$" "^String value is: strength$"
expect "ros2 service call /wm_manager/status ... (preset:=human-like: faces runs episodes, k = 1)" "$work/status.out" \
  '"running":\{"faces":\{[^}]*"policy":"episodes"' '"running":\{"faces":\{[^}]*"episode_window":1[,}]'
stop preset
[ "$rc" = 0 ] && pass "Ctrl-C on $preset" || fail "Ctrl-C on $preset" "exit $rc"

# --- a namespace, a lexicon, REG's settings, and a simulator's /clock (scripts/simulator_clock.py)
ns="ros2 launch fsreg_ros fsreg.launch.py kb:=$kb namespace:=cli_check use_sim_time:=true lexicon:=$repo/config/lexicon.yaml algorithm:=sd-pia wm_order:=mru-first capacity:=3 state_dir:=$work/state"
# shellcheck disable=SC2086
start ns $ns
if ready /cli_check; then pass "$ns (ready)"; else fail "$ns (ready)" "no ready status within 120 s"; fi
run n1 ros2 param get /cli_check/reg wm_order
run n2 ros2 param get /cli_check/reg lexicon
run n3 ros2 param get /cli_check/wm_manager capacity
cat "$work/n1.out" "$work/n2.out" "$work/n3.out" > "$work/n.out"
expect "ros2 param get /cli_check/reg wm_order, lexicon; /cli_check/wm_manager capacity" "$work/n.out" \
  "String value is: mru-first$" "String value is: $repo/config/lexicon.yaml$" "Integer value is: 3$"
epoch=$(python3 -c 'import time; print(time.monotonic() - 100)')
start simclock python3 "$repo/scripts/simulator_clock.py" /cli_check/clock 100 "$epoch"
sleep 4
status /cli_check
expect "scripts/simulator_clock.py /cli_check/clock 100 EPOCH (the graph follows it)" "$work/status.out" \
  '"time":1[0-9][0-9]\.' '"next_tick":\{"faces":null\}'
stop simclock
stop ns
[ "$rc" = 0 ] && pass "Ctrl-C on $ns" || fail "Ctrl-C on $ns" "exit $rc"

# --- by hand, as config/*.yaml say: ros2 run each node, then play the scenario with the dialogue player
for node in consultant wm_manager parser reference_resolution reg; do
  extra=()
  case $node in
    consultant) extra=(-r __node:=consultant_faces -p "kb:=$kb" -p "state_dir:=$work/state_run") ;;
    parser) extra=(-p "kb:=$kb") ;;
  esac
  start "run_$node" ros2 run fsreg_ros "$node" --ros-args --params-file config/guess_who.yaml "${extra[@]}" -p use_sim_time:=true
done
if ready ""; then pass "ros2 run fsreg_ros <node> --ros-args --params-file config/guess_who.yaml ... (every node; ready)"
else fail "ros2 run fsreg_ros <node> --ros-args --params-file config/guess_who.yaml ... (every node; ready)" "no ready status within 120 s"; fi
player="ros2 run fsreg_ros dialogue_player --ros-args --params-file config/dialogue_player.yaml -p scenario:=$kb"
(cd "$repo" && timeout -s INT 120 ros2 run fsreg_ros dialogue_player --ros-args --params-file config/dialogue_player.yaml \
  -p "scenario:=$kb") > "$work/player.out" 2>&1
rc=$?
echo "exit $rc" >> "$work/player.out"
expect "$player" "$work/player.out" "^exit 0$" '^ +11 +86\.00 +robot +face1 .*"the person with' "^human turns:"
for node in consultant wm_manager parser reference_resolution reg; do
  stop "run_$node"
  [ "$rc" = 0 ] && pass "Ctrl-C on ros2 run fsreg_ros $node" || fail "Ctrl-C on ros2 run fsreg_ros $node" "exit $rc"
done
run bad_run ros2 run fsreg_ros consultant --ros-args -r __node:=consultant_faces --params-file "$repo/config/consultant.yaml" -p "kb:=$work/none.yaml"
if [ "$rc" = 2 ] && [ "$(grep -c "cannot start: $work/none.yaml: file not found" "$work/bad_run.out")" = 1 ] && ! grep -q Traceback "$work/bad_run.out"; then
  pass "ros2 run fsreg_ros consultant ... -p kb:=none.yaml (one line, exit 2)"
else
  fail "ros2 run fsreg_ros consultant ... -p kb:=none.yaml (one line, exit 2)" "exit $rc: $(tr '\n' ' ' < "$work/bad_run.out" | cut -c1-300)"
fi

if [ -n "$intruders" ]; then
  echo "$me: error: another graph joined ROS domain $ROS_DOMAIN_ID during the run (twice: $intruders): the results above are not trustworthy; use a free domain"
  exit 2
fi
if [ "$failures" -gt 0 ]; then
  echo "$me: $failures broken promise(s)"
  exit 1
fi
echo "$me: every promise holds"
