"""The ROS 2 network environment of every fsreg process: loopback only unless widened.

On one machine no fsreg node may listen on a non-loopback address or send a packet
off the host.  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` alone only limits where
discovery is *sent*; Fast DDS still binds its ports on every interface.  So
:func:`ros_environment` also points Fast DDS at the default participant profile
``config/fastdds_localhost.xml`` (builtin transports off; shared memory plus a UDPv4
transport whitelisting 127.0.0.1).

Anything in the caller's environment that would widen this (a discovery range other
than LOCALHOST, including an empty one, which rcl reads as SUBNET; static peers; a
discovery server; a Fast DDS profile of one's own, in a profile variable or as
``DEFAULT_FASTRTPS_PROFILES.xml`` / ``DEFAULT_FASTDDS_PROFILES.xml`` in the working
directory, which Fast DDS loads after ours; a ``FASTDDS_ENVIRONMENT_FILE``, through
which Fast DDS reads a discovery server or peers) is refused with a one-line
:class:`NetworkRefused`, unless the user widens deliberately with
``FSREG_ALLOW_NETWORK=1`` (see docs/deployment.md).  Then the network variables are
left exactly as the user set them and no profile is imposed.

The policy holds wherever a node starts: the runners and scripts build the environment
of what they start with :func:`ros_environment`, and every node's ``main()``
(:func:`fsreg_ros.ros.node_base.run_node`, so ``ros2 run`` and the launch file too)
applies :func:`enforce_loopback` to its own environment before ROS starts.

``python -m fsreg_ros.ros.network`` prints the environment as shell ``export`` lines
(``scripts/rosenv.sh`` evaluates them), or the refusal and exit status 2.
"""

from __future__ import annotations

import os
import shlex
import sys
import tempfile
from pathlib import Path
from typing import Optional

from ..core.io.paths import config_path

#: Set to 1 to let DDS use the network (multi-machine deployment, docs/deployment.md).
ALLOW_NETWORK = "FSREG_ALLOW_NETWORK"
LOCALHOST = "LOCALHOST"
DISCOVERY_RANGE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
PROFILE_FILE = "fastdds_localhost.xml"
#: Fast DDS reads the first name (2.x); later releases the second.  Both get the profile.
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
#: Variables that send DDS traffic to other machines when set to anything.
WIDENING_VARIABLES = ("ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER")
#: A JSON file from which Fast DDS reads variables (a discovery server, peers) behind the environment's back.
ENVIRONMENT_FILE = "FASTDDS_ENVIRONMENT_FILE"
#: Profiles Fast DDS loads from the working directory, after (and over) the profile variables' file.
WORKING_DIRECTORY_PROFILES = ("DEFAULT_FASTRTPS_PROFILES.xml", "DEFAULT_FASTDDS_PROFILES.xml")
EXIT_REFUSED = 2


class NetworkRefused(ValueError):
    """The environment would let DDS leave this machine and the user did not allow it."""


def loopback_profile() -> Path:
    """Return the shipped Fast DDS profile that keeps DDS on loopback."""
    return config_path(PROFILE_FILE)


def is_loopback_profile(path: str) -> bool:
    """Return whether ``path`` is fsreg's loopback profile: the shipped file, or a copy of it.

    (A process started from a source tree and one from a colcon install name two copies.)
    """
    ours = loopback_profile()
    if path == str(ours):
        return True
    try:
        return Path(path).read_bytes() == ours.read_bytes()
    except OSError:
        return False


def network_allowed(env: dict) -> bool:
    """Return whether the user widened deliberately (``FSREG_ALLOW_NETWORK=1``)."""
    return env.get(ALLOW_NETWORK, "").strip().lower() in ("1", "true", "yes")


def check_loopback(env: dict, cwd: Optional[str] = None) -> None:
    """Raise :class:`NetworkRefused` if ``env`` (in working directory ``cwd``) would take DDS off this machine.

    ``cwd`` defaults to the current directory.
    """
    hint = f"unset it, or set {ALLOW_NETWORK}=1 to use the network deliberately (docs/deployment.md)"
    if DISCOVERY_RANGE in env and env[DISCOVERY_RANGE] != LOCALHOST:
        raise NetworkRefused(
            f"{DISCOVERY_RANGE}={env[DISCOVERY_RANGE]!r} would send DDS discovery off this machine "
            f"(fsreg needs {LOCALHOST}); {hint}"
        )
    for name in WIDENING_VARIABLES:
        if env.get(name, "").strip():
            raise NetworkRefused(f"{name}={env[name]!r} would connect DDS to other machines; {hint}")
    if env.get(ENVIRONMENT_FILE, "").strip():
        raise NetworkRefused(f"{ENVIRONMENT_FILE}={env[ENVIRONMENT_FILE]!r} lets Fast DDS read a discovery server "
                             f"or peers from a file; {hint}")
    profile = str(loopback_profile())
    for name in PROFILE_VARIABLES:
        if env.get(name) and not is_loopback_profile(env[name]):
            raise NetworkRefused(
                f"{name}={env[name]!r} replaces fsreg's loopback profile ({profile}); {hint}"
            )
    directory = Path(os.getcwd() if cwd is None else cwd)
    for name in WORKING_DIRECTORY_PROFILES:
        if (directory / name).exists():
            raise NetworkRefused(
                f"{directory / name} (a Fast DDS profile in the working directory) replaces fsreg's loopback "
                f"profile; move it, run from another directory, or set {ALLOW_NETWORK}=1 to use the network "
                "deliberately (docs/deployment.md)"
            )


def enforce_loopback(env: dict, allow_network: Optional[bool] = None) -> dict:
    """Make ``env`` (changed in place, and returned) keep DDS on this machine, unless the network is allowed.

    Unless the network is allowed (``allow_network``, or when None the
    ``FSREG_ALLOW_NETWORK`` variable of ``env``), check that nothing widens DDS
    (:class:`NetworkRefused` otherwise), set discovery to LOCALHOST and load the
    loopback profile.  Nothing else is touched (a node keeps the domain id it was given).
    """
    allowed = network_allowed(env) if allow_network is None else allow_network
    if not allowed:
        check_loopback(env)
        env[DISCOVERY_RANGE] = LOCALHOST
        for name in PROFILE_VARIABLES:
            env[name] = str(loopback_profile())
    return env


def ros_environment(base: Optional[dict] = None, allow_network: Optional[bool] = None) -> dict:
    """Return the environment for every fsreg ROS process a runner or script starts.

    Start from ``base`` (default ``os.environ``), apply :func:`enforce_loopback`, and
    add a domain id and a log directory when unset.
    """
    env = enforce_loopback(dict(os.environ if base is None else base), allow_network)
    env.setdefault(DISCOVERY_RANGE, LOCALHOST)
    env.setdefault("ROS_DOMAIN_ID", str(20 + os.getpid() % 70))
    if "ROS_LOG_DIR" not in env:
        env["ROS_LOG_DIR"] = tempfile.mkdtemp(prefix="fsreg-roslog-")
    return env


def require_loopback(prog: str, base: Optional[dict] = None) -> None:
    """Refuse a widening environment (unless allowed): print one line and exit 2."""
    env = os.environ if base is None else base
    if network_allowed(env):
        return
    try:
        check_loopback(env)
    except NetworkRefused as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        raise SystemExit(EXIT_REFUSED) from None


def use_loopback_environment(prog: str) -> None:
    """Give this process the fsreg ROS environment, or refuse a widening one (one line, exit 2).

    For a script that starts ROS in its own process: call it before rclpy is imported
    (:func:`require_loopback`, then :func:`ros_environment` into ``os.environ``).
    """
    require_loopback(prog)
    os.environ.update(ros_environment())


def shell_exports(env: dict, before: dict) -> str:
    """Return ``export`` lines for the variables of ``env`` that differ from ``before``."""
    changed = sorted(k for k, v in env.items() if before.get(k) != v)
    return "".join(f"export {k}={shlex.quote(env[k])}\n" for k in changed)


def main(argv: Optional[list[str]] = None) -> int:
    """Print the fsreg ROS environment as shell exports (for ``scripts/rosenv.sh``)."""
    args = sys.argv[1:] if argv is None else argv
    prog = args[0] if args else "fsreg"
    require_loopback(prog)
    env = ros_environment()
    sys.stdout.write(shell_exports(env, dict(os.environ)))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
