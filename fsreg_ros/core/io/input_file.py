"""Opening a user's file safely: the one owner of "is this a file the tools may read, and read it bounded".

Every file a tool reads because a user named it (a scenario, a params file, a lexicon, a
recording's ``metadata.yaml`` and ``.mcap``, a corpus) goes through here:

* it is opened without blocking (``O_NONBLOCK``: opening a named pipe that no one
  writes would wait forever) and must be a *regular* file -- a FIFO, a device (a link to
  ``/dev/zero`` or ``/dev/urandom``), a socket or a directory is refused;
* it may not be larger than the limit its kind allows, and it is read with that limit
  (a file that grows while read is still cut at the limit and refused).

A refusal is one :class:`InputFileError` whose text is ``"{path}: {what is wrong}"``.
:func:`read_bytes` reads a whole file; :func:`open_binary` hands a checked, blocking
file object to a reader that streams (CSV, a bag); :func:`json_lines` reads a JSON
Lines file (a corpus, an event trace) value by value, a bad line named by its line
and column; :func:`check_file` checks a file that a third-party library opens by name
itself.  YAML's own limits (depth, aliases) are
:mod:`fsreg_ros.core.io.yaml_source`'s, which reads its text here.
"""

from __future__ import annotations

import io
import json
import os
import stat
from typing import Any, BinaryIO, Iterator, TextIO, Union

#: The default limit: files larger than this are refused before reading (a world of 10,000 entities is ~2 MB).
MAX_FILE_BYTES = 64 * 1024 * 1024
#: The limit of a corpus or an event trace read line by line (the tangram corpus is ~2 MB, TUNA's trials KB each).
MAX_CORPUS_BYTES = 1024 ** 3

PathLike = Union[str, os.PathLike]

#: What a file is, in words, by ``stat`` test: the one wording of every message that names a file's kind
#: (a tool refusing an input here, a consultant refusing its state database, :mod:`fsreg_ros.core.state.store`).
FILE_KINDS = ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
              (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str:
    """Return what a file of ``mode`` is, in words (``a named pipe (FIFO)``)."""
    for test, words in FILE_KINDS:
        if test(mode):
            return words
    return f"a special file (mode {mode:o})"


class InputFileError(ValueError):
    """A file the tools will not read: ``str(err)`` is one line, ``"{source}: {message}"``."""

    def __init__(self, source: str, message: str) -> None:
        self.source, self.message = source, message
        super().__init__(f"{source}: {message}")

    def __reduce__(self) -> tuple:
        return (type(self), (self.source, self.message))


def _problem(mode: int) -> str:
    return "is a directory, not a file" if stat.S_ISDIR(mode) else f"is {file_kind(mode)}, not a regular file"


def _reason(err: OSError) -> str:
    return err.strerror or str(err)


def _too_large(limit: int) -> str:
    return f"too large: over {limit:,} bytes"


def _open_checked(path: PathLike, limit: int) -> int:
    """Return a descriptor of ``path`` opened without blocking, checked regular and within ``limit`` bytes."""
    source = os.fspath(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputFileError(source, "file not found") from None
    except OSError as err:
        raise InputFileError(source, f"cannot read the file: {_reason(err)}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise InputFileError(source, _problem(info.st_mode))
        if info.st_size > limit:
            raise InputFileError(source, _too_large(limit))
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_bytes(path: PathLike, limit: int = MAX_FILE_BYTES) -> bytes:
    """Return the bytes of the regular file ``path``, at most ``limit`` of them; InputFileError otherwise."""
    source = os.fspath(path)
    fd = _open_checked(path, limit)
    try:
        with os.fdopen(fd, "rb") as handle:
            fd = -1  # the handle owns it now
            data = handle.read(limit + 1)
    except OSError as err:
        raise InputFileError(source, f"cannot read the file: {_reason(err)}") from None
    finally:
        if fd >= 0:
            os.close(fd)
    if len(data) > limit:
        raise InputFileError(source, _too_large(limit))
    return data


def read_text(path: PathLike, limit: int = MAX_FILE_BYTES) -> str:
    """Return the UTF-8 text of the regular file ``path`` (:func:`read_bytes`); NUL bytes and bad UTF-8 refused."""
    data = read_bytes(path, limit)
    nul = data.find(b"\0")
    if nul >= 0:
        raise InputFileError(os.fspath(path), f"not a text file: NUL byte at offset {nul}")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputFileError(os.fspath(path), f"not UTF-8 text ({err.reason} at byte {err.start})") from None


def open_binary(path: PathLike, limit: int = MAX_FILE_BYTES) -> BinaryIO:
    """Return the regular file ``path`` opened for reading in binary (blocking again), checked as :func:`read_bytes`.

    For readers that stream (a CSV, a corpus): the file was checked when opened.
    """
    fd = _open_checked(path, limit)
    try:
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def open_text(path: PathLike, limit: int = MAX_FILE_BYTES) -> TextIO:
    """Return the regular file ``path`` opened as UTF-8 text (``newline=""``, for ``csv``); see :func:`open_binary`."""
    return io.TextIOWrapper(open_binary(path, limit), encoding="utf-8", newline="")


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


#: JSON as written (RFC 8259): ``NaN`` and ``Infinity``, which Python's json module reads, are refused.
_DECODER = json.JSONDecoder(parse_constant=_no_constant)


def json_lines(path: PathLike, limit: int = MAX_CORPUS_BYTES) -> Iterator[tuple[int, Any]]:
    """Yield ``(line number, value)`` of each non-blank line of the JSON Lines file ``path`` (from 1).

    The file is checked and bounded as :func:`open_binary` does (and refused if it grows past
    ``limit`` while read).  A line that is not one JSON value in UTF-8 is one
    :class:`InputFileError` naming the line and, where the decoder gives one, the column:
    ``"{path}: line 3, column 12: not JSON (Expecting ',' delimiter)"``.  What a value must be
    is the caller's to check.
    """
    source = os.fspath(path)
    read = 0
    with open_binary(path, limit) as handle:
        for number, raw in enumerate(handle, 1):
            read += len(raw)
            if read > limit:
                raise InputFileError(source, _too_large(limit))
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as err:
                raise InputFileError(source, f"line {number}, column {err.start + 1}: not UTF-8 text "
                                             f"({err.reason})") from None
            if not text.strip():
                continue
            try:
                value = _DECODER.decode(text.rstrip("\r\n"))  # an error at the end is on this line
            except json.JSONDecodeError as err:
                raise InputFileError(source, f"line {number}, column {err.colno}: not JSON ({err.msg})") from None
            except RecursionError:
                raise InputFileError(source, f"line {number}: not JSON (nested too deeply)") from None
            except ValueError as err:  # a constant refused above, or an integer over Python's digit limit
                raise InputFileError(source, f"line {number}: not JSON ({str(err).split(':')[0]})") from None
            yield number, value


def check_file(path: PathLike, limit: int = MAX_FILE_BYTES) -> None:
    """Refuse ``path`` unless it is a regular file within ``limit`` bytes (for a library that opens it by name)."""
    os.close(_open_checked(path, limit))


__all__ = ["FILE_KINDS", "MAX_CORPUS_BYTES", "MAX_FILE_BYTES", "InputFileError", "check_file", "file_kind",
           "json_lines", "open_binary", "open_text", "read_bytes", "read_text"]
