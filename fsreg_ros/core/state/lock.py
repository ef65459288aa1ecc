"""The state database's lock file: one opener at a time, and a refused one told who holds it.

A lock file beside the database (``<file>.lock``) is held with an exclusive ``flock``
(which also excludes a second opener in the same process) plus a POSIX record lock on
the same file, so a refused opener names the real holder as the kernel reports it
(``F_GETLK``; ``/proc/locks`` for a holder that took only the ``flock``), never a PID read
from the file (which the file also holds, for people).  :class:`~fsreg_ros.core.state.store.DomainStore`
takes and releases it; the messages naming the database are the store's.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

from ..io.input_file import file_kind

#: Lock files held by this process, by (device, inode): a second opener here is refused without
#: opening the file (closing any descriptor of it would drop this process's POSIX record lock).
_HELD: dict[tuple[int, int], Path] = {}
#: ``struct flock`` on Linux (short l_type, short l_whence, off_t l_start, off_t l_len, pid_t l_pid).
_FLOCK = "@hhqqixxxx"


class LockHeld(OSError):
    """Another holder has the lock: ``holder`` names it (``process 123 (its command line)``)."""

    def __init__(self, holder: str) -> None:
        super().__init__(holder)
        self.holder = holder


class LockNotRegular(OSError):
    """The lock file's path is not a regular file: ``kind`` says what it is, in words."""

    def __init__(self, kind: str) -> None:
        super().__init__(kind)
        self.kind = kind


@dataclass(frozen=True)
class HeldLock:
    """A lock file this process holds: its open descriptor and its (device, inode)."""

    fd: int
    key: tuple[int, int]

    def release(self) -> None:
        """Release the lock (closing the descriptor drops the flock and the record lock)."""
        _HELD.pop(self.key, None)
        os.close(self.fd)


def take_lock(lock_path: Path, owner: Path) -> HeldLock:
    """Take the lock file ``lock_path`` for ``owner`` (the database), writing this PID in it.

    Raises :class:`LockHeld` naming the holder (this process too), :class:`LockNotRegular`
    when the path is a FIFO, a directory, a device ..., or ``OSError``.
    """
    try:
        st = os.stat(lock_path)
    except FileNotFoundError:
        st = None
    if st is not None and (st.st_dev, st.st_ino) in _HELD:
        raise LockHeld(f"process {os.getpid()} (this process)")
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise LockNotRegular(file_kind(info.st_mode))
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise LockHeld(lock_holder(fd, info)) from None
            raise
        try:  # the record lock names this process to the kernel, for the next refused opener
            fcntl.fcntl(fd, fcntl.F_SETLK, struct.pack(_FLOCK, fcntl.F_WRLCK, os.SEEK_SET, 0, 0, 0))
        except OSError:
            pass  # a file system without record locks: the flock still excludes
    except BaseException:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
    held = HeldLock(fd, (info.st_dev, info.st_ino))
    _HELD[held.key] = owner
    return held


def lock_holder(fd: int, info: os.stat_result) -> str:
    """Name the process holding the lock on the open lock file ``fd``, as the kernel reports it.

    ``F_GETLK`` reports the holder of the record lock this module takes beside its
    ``flock``; a holder that took only the ``flock`` (an older version) is looked up in
    ``/proc/locks`` by the file's device and inode.
    """
    pid = 0
    try:
        reply = fcntl.fcntl(fd, fcntl.F_GETLK, struct.pack(_FLOCK, fcntl.F_WRLCK, os.SEEK_SET, 0, 0, 0))
        kind, _, _, _, holder = struct.unpack(_FLOCK, reply)
        if kind != fcntl.F_UNLCK and holder > 0:
            pid = holder
    except OSError:
        pass
    if not pid and sys.platform.startswith("linux"):
        pid = _proc_locks_holder(info)
    if not pid:
        return "another process (the kernel does not say which)"
    return f"process {pid}{_command_of(pid)}"


def _proc_locks_holder(info: os.stat_result) -> int:
    wanted = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    try:
        with open("/proc/locks", encoding="ascii", errors="replace") as handle:
            for line in handle:
                fields = line.split()
                if "->" in fields:
                    continue  # a waiter, not a holder
                if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == wanted and fields[4].isdigit():
                    return int(fields[4])
    except OSError:
        pass
    return 0


def _command_of(pid: int) -> str:
    """Return `` (<command line>)`` of a process, shortened, or nothing if it cannot be read."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as handle:
            words = handle.read(4096).split(b"\0")
    except OSError:
        return ""
    text = " ".join(w.decode("utf-8", "replace") for w in words if w)
    text = "".join(ch if ch.isprintable() else "?" for ch in text)
    return f" ({text[:120]}{'...' if len(text) > 120 else ''})" if text else ""
