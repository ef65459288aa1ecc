#!/usr/bin/env bash
# Fault probe of the tools' file inputs, record folders and view host (issues 37.8, 38.5, 38.7): each hostile
# input through the command a user runs, 20 s deadline each; prints one line per case and the counts.
# A case passes ("ok") when the command exits 2 with exactly one line on stderr; HANG = killed at 20 s.
#
#   scripts/probe_file_inputs.sh            (set ROS_DOMAIN_ID to a domain of your own first)
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
. "$root/scripts/rosenv.sh"
B="$root/.venv/bin"
S="$root/scenarios/guess_who_table1.yaml"
W="$(mktemp -d "${TMPDIR:-/tmp}/fsreg-probe.XXXXXX")"
trap 'rm -rf "$W"' EXIT
"$B/python" - "$W/bag" "$S" <<'PY'
import json, sys
from fsreg_ros.core.io.recording import STRING, TOPICS_KEY, BagWriter, Channel
writer = BagWriter(sys.argv[1], [Channel("/r/rr/result", STRING, 10)], custom={TOPICS_KEY: json.dumps({"/r/rr/result": "rr"})})
writer.attach("scenario", sys.argv[2])
writer.close()
PY
"$B/python" - "$W" <<'PY'
import sys
root = sys.argv[1]
open(f"{root}/deep.yaml", "w").write("[" * 5000 + "]" * 5000 + "\n")
open(f"{root}/bomb.yaml", "w").write("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    c + ": &" + c + " [" + ", ".join(["*" + p] * 10) + "]\n" for p, c in zip("abcdefgh", "bcdefghi")))
open(f"{root}/big.yaml", "w").write("a: " + "x" * (70 * 1024 * 1024) + "\n")
PY
mk() {  # mk PATH KIND: a FIFO, a link to /dev/zero or /dev/urandom, or a copy of a prepared YAML
  rm -f "$1"
  case $2 in
    fifo) mkfifo "$1" ;;
    zero) ln -s /dev/zero "$1" ;;
    urandom) ln -s /dev/urandom "$1" ;;
    *) cp "$W/$2.yaml" "$1" ;;
  esac
}
ok=0; bad=0
run() {  # run NAME COMMAND...: one line of verdict
  local name=$1 out rc lines verdict
  shift
  out=$(timeout 20 "$@" 2>&1 >/dev/null); rc=$?
  lines=$(printf '%s' "$out" | grep -c '')
  if [ "$rc" = 124 ]; then verdict=HANG
  elif [ "$rc" = 2 ] && [ "$lines" = 1 ]; then verdict=ok
  else verdict="BAD(exit $rc, $lines lines)"; fi
  if [ "$verdict" = ok ]; then ok=$((ok + 1)); else bad=$((bad + 1)); fi
  printf '%-32s %-20s %s\n' "$name" "$verdict" "$(printf '%s' "$out" | tail -1 | cut -c1-120)"
}
for c in fifo zero urandom big deep bomb; do
  mk "$W/p.yaml" $c; run "up --params-file $c" "$B/fsreg-up" "$S" --namespace /fsreg_probe --params-file "$W/p.yaml"
done
for c in fifo zero deep bomb; do
  cp -r "$W/bag" "$W/b-$c"; mk "$W/b-$c/metadata.yaml" $c
  run "sim --replay metadata $c" "$B/fsreg-sim" --replay "$W/b-$c"
  run "plot metadata $c" "$B/fsreg-plot" "$W/b-$c" -o "$W/x.png"
done
for c in fifo zero; do
  cp -r "$W/bag" "$W/m-$c"; mk "$W/m-$c/bag.mcap" $c
  run "sim --replay mcap $c" "$B/fsreg-sim" --replay "$W/m-$c"
  run "plot mcap $c" "$B/fsreg-plot" "$W/m-$c" -o "$W/x.png"
done
for c in fifo zero deep bomb; do
  mk "$W/s.yaml" $c
  run "sim scenario $c" "$B/fsreg-sim" "$W/s.yaml"
  run "sim --lexicon $c" "$B/fsreg-sim" "$S" --lexicon "$W/s.yaml"
done
for h in '' 0 0.0.0.0 '::'; do  # each must be refused (wildcard hosts)
  run "ctl view --host '$h'" "$B/fsreg-ctl" --namespace /fsreg_probe view --host "$h" --port 0 --timeout 1
done
long="$W/$(printf 'r%.0s' $(seq 300))"
run "ctl record: name too long" "$B/fsreg-ctl" record "$long"
run "up --record: name too long" "$B/fsreg-up" "$S" --namespace /fsreg_probe --record "$long"
echo "probe: $ok ok, $bad not (of $((ok + bad)))"
