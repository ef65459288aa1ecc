# Sourced by the fsreg scripts: the ROS 2 environment every process here runs with.
# DDS stays on this machine: LOCALHOST discovery plus the Fast DDS loopback profile
# (config/fastdds_localhost.xml), both set by fsreg_ros.ros.network.  An environment that
# would widen it (another discovery range, ROS_STATIC_PEERS, ROS_DISCOVERY_SERVER, a
# profile of your own) is refused with exit 2 unless FSREG_ALLOW_NETWORK=1 (docs/deployment.md;
# README "Running on several machines").  Needs the venv (scripts/venv.sh) or FSREG_PYTHON.
_fsreg_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export ROS_LOG_DIR="${ROS_LOG_DIR:-${TMPDIR:-/tmp}/fsreg-ros-log-$(id -u)}"
mkdir -p "$ROS_LOG_DIR"
if [ -z "${ROS_DOMAIN_ID:-}" ]; then export ROS_DOMAIN_ID=$(( 20 + $$ % 70 )); fi
if ! _fsreg_exports="$(PYTHONPATH="$_fsreg_root${PYTHONPATH:+:$PYTHONPATH}" \
    "${FSREG_PYTHON:-$_fsreg_root/.venv/bin/python}" -m fsreg_ros.ros.network "$(basename "$0")")"; then
  return 2 2>/dev/null || exit 2
fi
eval "$_fsreg_exports"
unset _fsreg_exports _fsreg_root
if [ -n "${FSREG_ALLOW_NETWORK:-}" ]; then
  echo "fsreg: note: FSREG_ALLOW_NETWORK is set: DDS may use the network as your environment says" >&2
fi
