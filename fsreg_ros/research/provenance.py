"""What code and environment a run used: the checkout's commit and changes, Python and library versions.

A sweep's manifest and games file record them (:func:`git_state`, :func:`environment`),
so a result names the code that produced it and a resume or merge refuses other code
(:mod:`fsreg_ros.research.ledger`).
"""

from __future__ import annotations

import hashlib
import platform
import subprocess
from pathlib import Path
from typing import Any, Optional, Sequence


def _git(*args: str, cwd: Optional[Path] = None) -> Optional[bytes]:
    try:
        done = subprocess.run(["git", *args], cwd=cwd or Path(__file__).parent, capture_output=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout if done.returncode == 0 else None


def git_state(exclude: Sequence[Path] = (), where: Optional[Path] = None) -> dict:
    """Return the checkout's commit, whether the tree is dirty, the SHA-256 of its changes and what changed.

    The changes are the whole repository's ``git diff HEAD --binary`` plus every
    untracked, not ignored file under the repository (name and content), whatever
    directory the package sits in; ``changed_files`` and ``untracked_files`` name them.
    Untracked files under ``exclude`` (a sweep's own output directory) are left out.
    ``where``: a directory of the checkout (default: this package's).  A hash that
    cannot be taken is null with the reason in ``diff_absent``: a clean tree, no git
    checkout, or git failing.
    """
    top_text = _git("rev-parse", "--show-toplevel", cwd=where)
    if top_text is None:
        return {"commit": None, "dirty": None, "diff_sha256": None,
                "diff_absent": "not a git checkout (or git is not installed)"}
    top = Path(top_text.decode().strip())
    commit = _git("rev-parse", "HEAD", cwd=top)
    diff = _git("diff", "HEAD", "--binary", cwd=top)
    names = _git("diff", "HEAD", "--name-only", "-z", cwd=top)
    others = _git("ls-files", "--others", "--exclude-standard", "-z", cwd=top)
    if commit is None or diff is None or names is None or others is None:
        return {"commit": commit.decode().strip() if commit else None, "dirty": None, "diff_sha256": None,
                "diff_absent": "git failed to report the changes"}
    skip = []
    for path in exclude:
        try:
            skip.append(Path(path).resolve().relative_to(top.resolve()).as_posix().rstrip("/") + "/")
        except ValueError:
            pass  # outside the repository: never listed
    untracked = sorted(n.decode(errors="surrogateescape") for n in others.split(b"\0") if n)
    untracked = [n for n in untracked if not any((n + "/").startswith(p) or n.startswith(p) for p in skip)]
    changed = sorted(n.decode(errors="surrogateescape") for n in names.split(b"\0") if n)
    dirty = bool(diff) or bool(untracked)
    state: dict[str, Any] = {"commit": commit.decode().strip(), "dirty": dirty, "diff_sha256": None,
                             "changed_files": changed, "untracked_files": untracked}
    if not dirty:
        state["diff_absent"] = "clean tree: no tracked change and no untracked file"
        return state
    digest = hashlib.sha256(diff)
    for name in untracked:
        digest.update(b"\0untracked\0" + name.encode(errors="surrogateescape") + b"\0")
        try:
            with (top / name).open("rb") as data:
                for chunk in iter(lambda: data.read(1 << 20), b""):
                    digest.update(chunk)
        except OSError as err:
            digest.update(f"<unreadable: {err.strerror}>".encode())
    state["diff_sha256"] = digest.hexdigest()
    return state


def git_commit() -> Optional[str]:
    """Return the repository's HEAD commit, or None outside a git checkout."""
    return git_state()["commit"]


def package_version(name: str = "fsreg_ros") -> str:
    """Return an installed distribution's version (or "unknown")."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return "unknown"


#: Libraries whose versions a manifest records.
LIBRARIES = ("numpy", "matplotlib", "tqdm", "pyyaml", "pydantic")


def environment() -> dict:
    """Return the Python, platform and library versions a run used."""
    return {
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "libraries": {name: package_version(name) for name in LIBRARIES},
    }
