#!/usr/bin/env bash
# Run the test suite in .venv, creating or refreshing it first.  Extra arguments go to pytest.
#
#   scripts/test.sh                  everything: core, nodes, in-process and multi-process graphs, colcon build
#                                    (1,403 tests; on two workers: docs/testing.md has the run times)
#   scripts/test.sh --quick          the quick suite, -m "not slow": no multi-process graphs, no colcon, no
#                                    generated fuzzing (1,304 tests)
#   scripts/test.sh -m slow          only the slow tests
#   scripts/test.sh test/core/test_x.py -k name -q     (any pytest arguments; named tests run in one process)
#
# With no test named, the run goes to 2 pytest-xdist workers (FSREG_TEST_WORKERS=N to choose, -n 0 for none),
# worker N on ROS domain ROS_DOMAIN_ID + N.  Tests that start a graph of node processes or run for more than
# a few seconds are marked slow (pytest.ini).  Set ROS_DOMAIN_ID to a domain of your own (the next one free too).
set -euo pipefail
if [[ " $* " == *" --help "* || "${1:-}" == "-h" ]]; then
    sed -n '2,13s/^# \{0,1\}//p' "$0"
    exit 0
fi
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/venv.sh"
# The live view's browser test needs Debian's chromium (test/tools/test_view.py); install it where missing.
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "fsreg: installing chromium (the live view's browser test) ..." >&2
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium) >/dev/null 2>&1 \
            || { echo "fsreg: apt-get install chromium failed" >&2; exit 2; }
    else
        echo "fsreg: the tests need Debian's chromium: sudo apt-get install chromium" >&2
        exit 2
    fi
fi
. "$root/scripts/rosenv.sh"
cd "$root"
args=()
# The whole suite (no test named) runs on pytest-xdist workers, each on a ROS domain of its own
# (test/support/workers.py), whole files to a worker; named tests run in this process (no start-up).
workers=(-n "${FSREG_TEST_WORKERS:-2}" --dist loadfile --no-loadscope-reorder)  # slow modules first: test/conftest.py
for arg in "$@"; do  # --quick anywhere stands for -m "not slow"
    if [[ "$arg" == "--quick" ]]; then args+=(-m "not slow"); else args+=("$arg"); fi
    case "$arg" in
        -n|-n[0-9]*|--numprocesses|--numprocesses=*|no:xdist|-pno:xdist|--pdb|--trace) workers=() ;;  # caller's
        -*) ;;
        *) if [[ -z "${FSREG_TEST_WORKERS:-}" && -e "${arg%%::*}" ]]; then workers=(); fi ;;  # a test named
    esac
done
exec "$root/.venv/bin/python" -m pytest "${workers[@]}" "${args[@]}"
