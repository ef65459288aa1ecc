#!/usr/bin/env bash
# Create or refresh .venv with everything fsreg needs (ROS 2 Jazzy wheels, core, test
# tools), then install fsreg_ros itself in editable mode. Idempotent and quick when
# nothing changed: a stamp of the requirement files decides whether pip runs.
# Source it (`. scripts/venv.sh`) or run it; it never changes ROS network settings.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
python="${FSREG_PYTHON:-python3}"

if ! "$python" -c 'import sys; sys.exit(sys.version_info[:2] < (3, 10))' 2>/dev/null; then
  echo "fsreg: needs Python >= 3.10 (found: $("$python" --version 2>&1)); set FSREG_PYTHON" >&2
  exit 2
fi
if [ ! -x "$venv/bin/python" ]; then
  if ! "$python" -m venv "$venv" 2>/dev/null; then
    echo "fsreg: '$python -m venv' failed; on Debian: apt-get install python3-venv" >&2
    exit 2
  fi
fi
stamp="$venv/.fsreg-stamp"
want="$(cat "$root"/requirements*.txt "$root/setup.py" "$root/setup.cfg" | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "fsreg: installing dependencies into $venv ..." >&2
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip >&2
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$root/requirements-dev.txt" >&2
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps -e "$root" >&2
  echo "$want" > "$stamp"
fi
