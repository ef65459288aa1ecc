# Sourced by the fsreg scripts: the ROS 2 environment every process here runs with.
# Discovery stays on this machine unless the caller has deliberately chosen otherwise
# (see README "Running on several machines"); a private log directory is used.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( 20 + $$ % 70 ))}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-${TMPDIR:-/tmp}/fsreg-ros-log-$(id -u)}"
mkdir -p "$ROS_LOG_DIR"
if [ "$ROS_AUTOMATIC_DISCOVERY_RANGE" != "LOCALHOST" ]; then
  echo "fsreg: note: ROS_AUTOMATIC_DISCOVERY_RANGE=$ROS_AUTOMATIC_DISCOVERY_RANGE (set by you): traffic may leave this machine" >&2
fi
