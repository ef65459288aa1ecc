"""A session recording as a rosbag2 folder (MCAP storage): writing it, reading it back, what a cut-short one keeps.

The one module that serialises fsreg's messages to a bag and back, through the pure-Python
``rosbags`` library (no ROS install needed; the MCAP and the ``metadata.yaml`` are the
library's, never written by hand here).  What ``ros2 bag record -s mcap`` writes is what
this writes: one ``<name>.mcap`` per folder with every message's CDR bytes as they came off
the wire, each topic's offered QoS profiles, type hash (RIHS01) and message definition, and
a ``metadata.yaml`` (``ros2 bag info DIR`` reads it; Foxglove opens the ``.mcap``).

Writing (:class:`BagWriter`): an MCAP file gets its index and summary only when it is
closed, so a recorder killed mid-write would leave a file no reader opens.  The writer
therefore closes a *segment* every ``segment_seconds`` (1 s by default): each is a complete
rosbag2 folder of its own under ``DIR/segments/`` (``metadata.yaml`` and ``.mcap``).  At a
clean close the segments are merged into ``DIR/<name>.mcap`` plus ``DIR/metadata.yaml``
(written last, so a folder with a ``metadata.yaml`` is complete) and removed.  A recording
cut short (SIGKILL, power loss) keeps every closed segment; :func:`open_recording` reads
them and says what was lost: the segment that was open (at most ``segment_seconds`` of
messages) and the time from which messages are missing.

Reading (:func:`open_recording`): every message in time order, ``std_msgs/String`` decoded
as the JSON object it carries and ``rosgraph_msgs/Clock`` as seconds.  A folder or file that
is not a readable recording raises :class:`RecordingError`, one line naming the file and
the problem.  Files other than the bag's own (the knowledge the graph ran with, which a
recorder may copy to ``DIR/fsreg/``) are listed in the metadata's ``custom_data``
(``fsreg.*`` keys).
"""

from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Optional, Sequence

STRING = "std_msgs/msg/String"
CLOCK = "rosgraph_msgs/msg/Clock"
#: Where a recording keeps its closed segments until a clean close merges them.
SEGMENTS = "segments"
#: Where a recorder copies the files a replay needs (the knowledge base, the lexicon).
ATTACHED = "fsreg"
#: Seconds after which the open segment is closed (what a SIGKILL can lose at most).
SEGMENT_SECONDS = 1.0
#: Prefix of the ``custom_data`` keys fsreg writes.
CUSTOM_PREFIX = "fsreg."
#: What each recorded topic is: the recorder writes ``{topic name: role}`` as JSON under this
#: ``custom_data`` key, so a reader finds the topics of a namespaced or remapped graph by role.
TOPICS_KEY = "fsreg.topics"
ROLES = ("human", "semantics", "rr", "request", "expression", "state", "events", "announce", "ready", "assert",
         "assert_result", "clock")
#: The largest ``.mcap`` read back (a recording is read into memory whole; an hour of a busy graph is ~100 MB).
MAX_BAG_BYTES = 2 * 1024 ** 3
#: The largest ``metadata.yaml`` read back (``ros2 bag`` writes a few KB).
METADATA_MAX_BYTES = 16 * 1024 * 1024
#: RMW's "infinite" duration as ``ros2 bag`` writes it into QoS profiles.
_INFINITE = (9223372036, 854775807)


class RecordingError(ValueError):
    """A recording that cannot be written or read (one line: the file and the problem)."""


class WriteFailed(RecordingError):
    """Writing a recording failed (a full disk, a name the file system refuses): ``str(err)`` is the cause alone.

    Whatever was closed before stays readable (:func:`open_recording` reads a folder
    whose segments were never merged as a recording cut short).
    """

    def __init__(self, err: OSError) -> None:
        super().__init__(err.strerror or str(err))
        self.errno = err.errno


def check_target(path: Path) -> None:
    """Refuse a recording folder that exists or cannot be made (RecordingError, one line naming it and why)."""
    try:
        os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as err:  # a name longer than the file system allows, a component that is a file, ...
        raise RecordingError(f"{path}: cannot create it ({err.strerror or err})") from None
    raise RecordingError(f"{path} exists already; a recording goes to a new folder")


@dataclass(frozen=True)
class Channel:
    """One recorded topic: full name, ROS type and the QoS its writers offer (plain data)."""

    name: str
    msgtype: str
    depth: int = 10
    latched: bool = False
    lease: Optional[float] = None


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _qos(channel: Channel):
    """Return the channel's offered QoS profile as rosbags writes it (``ros2 bag``'s fields)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(*_INFINITE)
    lease = infinite
    if channel.lease is not None:
        lease = QosTime(int(channel.lease), int(round((channel.lease % 1) * 1e9)))
    durability = QosDurability.TRANSIENT_LOCAL if channel.latched else QosDurability.VOLATILE
    return Qos(QosHistory.KEEP_LAST, channel.depth, QosReliability.RELIABLE, durability, infinite, infinite,
               QosLiveliness.AUTOMATIC, lease, False)


# ----------------------------------------------------------------------- writing
class BagWriter:
    """Write one recording (see the module docstring): :meth:`write` raw CDR bytes, :meth:`close` once.

    ``path`` must not exist (as ``ros2 bag record`` refuses an existing folder).  ``custom``
    goes to the metadata's ``custom_data`` (strings).  ``now`` gives the wall clock in
    nanoseconds (the segment timer; tests pass their own).
    """

    def __init__(self, path: Path, channels: Sequence[Channel], *, segment_seconds: float = SEGMENT_SECONDS,
                 custom: Optional[dict[str, str]] = None, now: Callable[[], int] = time.time_ns) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = Path(path)
        check_target(self.path)
        if not segment_seconds > 0:
            raise RecordingError(f"segment length must be positive, got {segment_seconds!r}")
        self._writer_class, self._plugin = Writer, StoragePlugin.MCAP
        self.channels = {c.name: c for c in channels}
        self.segment_seconds = segment_seconds
        self.custom = dict(custom or {})
        self.now = now
        store = _typestore()
        self._definitions = {t: (store.generate_msgdef(t, ros_version=2)[0], store.hash_rihs01(t))
                             for t in {c.msgtype for c in channels}}
        self.counts = {name: 0 for name in self.channels}
        self.segments: list[Path] = []  # closed, complete
        self._writer = None
        self._connections: dict[str, Any] = {}
        self._opened = 0
        self.closed = False
        try:
            (self.path / SEGMENTS).mkdir(parents=True)
        except OSError as err:
            raise RecordingError(f"{self.path}: cannot create it ({err.strerror or err})") from None

    def attach(self, key: str, source: Path) -> None:
        """Copy file ``source`` into the recording (``fsreg/<name>``), named in ``custom_data`` as ``fsreg.<key>``."""
        target = self.path / ATTACHED / Path(source).name
        try:
            target.parent.mkdir(exist_ok=True)
            if target.exists():
                target = target.with_name(f"{key}-{target.name}")
            shutil.copyfile(source, target)
        except OSError as err:
            raise WriteFailed(err) from None
        self.custom[CUSTOM_PREFIX + key] = str(target.relative_to(self.path))

    def _open_segment(self) -> None:
        index = len(self.segments)
        folder = self.path / SEGMENTS / f"{index:06d}"
        writer = self._writer_class(folder, version=9, storage_plugin=self._plugin)
        writer.open()
        self._connections = {}
        for name, channel in self.channels.items():
            msgdef, digest = self._definitions[channel.msgtype]
            self._connections[name] = writer.add_connection(name, channel.msgtype, msgdef=msgdef, rihs01=digest,
                                                            offered_qos_profiles=[_qos(channel)])
        for key, value in self.custom.items():
            writer.set_custom_data(key, value)
        self._writer, self._opened = writer, self.now()

    def _close_segment(self) -> None:
        writer, self._writer = self._writer, None
        if writer is None:
            return
        for key, value in self.custom.items():  # attached after the segment opened
            writer.set_custom_data(key, value)
        writer.close()
        self.segments.append(writer.path)

    def write(self, topic: str, timestamp: int, data: bytes) -> None:
        """Write one message (its CDR bytes) received at ``timestamp`` ns; a topic not declared is an error."""
        if topic not in self.channels:
            raise RecordingError(f"{self.path}: topic {topic} was not declared for this recording")
        try:
            self.poll()
            if self._writer is None:
                self._open_segment()
            self._writer.write(self._connections[topic], timestamp, data)
        except OSError as err:
            raise WriteFailed(err) from None
        self.counts[topic] += 1

    def poll(self) -> None:
        """Close the open segment once it is ``segment_seconds`` old (call it now and then: a timer)."""
        if self._writer is not None and self.now() - self._opened >= self.segment_seconds * 1e9:
            try:
                self._close_segment()
            except OSError as err:
                raise WriteFailed(err) from None

    def close(self, merge: bool = True) -> Path:
        """Close the recording; with ``merge``, into one ``.mcap`` and ``metadata.yaml`` (else the segments stay).

        :class:`WriteFailed` if the disk refuses (full): what was closed before stays, and
        :func:`open_recording` reads it as a recording cut short.
        """
        if self.closed:
            return self.path
        self.closed = True
        try:
            self._close_segment()
            if not self.segments:  # nothing arrived: an empty bag with every topic, as ros2 bag leaves one
                self._open_segment()
                self._close_segment()
            if merge:
                self._merge()
        except OSError as err:  # the closed segments stay: read as a recording cut short
            self._writer = None
            shutil.rmtree(self.path / ".merge", ignore_errors=True)
            raise WriteFailed(err) from None
        return self.path

    def _merge(self) -> None:
        """Copy every segment's messages into one bag, commit it (``metadata.yaml`` last), drop the segments."""
        from rosbags.rosbag2 import Reader

        staging = self.path / ".merge"
        if staging.exists():
            shutil.rmtree(staging)
        folder = staging / self.path.name
        staging.mkdir()
        writer = self._writer_class(folder, version=9, storage_plugin=self._plugin)
        writer.open()
        connections = {}
        for name, channel in self.channels.items():
            msgdef, digest = self._definitions[channel.msgtype]
            connections[name] = writer.add_connection(name, channel.msgtype, msgdef=msgdef, rihs01=digest,
                                                      offered_qos_profiles=[_qos(channel)])
        for key, value in self.custom.items():
            writer.set_custom_data(key, value)
        for segment in self.segments:
            with Reader(segment) as reader:
                for connection, timestamp, data in reader.messages():
                    writer.write(connections[connection.topic], timestamp, data)
        writer.close()
        storage = folder / f"{self.path.name}.mcap"
        storage.replace(self.path / storage.name)
        (folder / "metadata.yaml").replace(self.path / "metadata.yaml")  # the commit: the folder is one bag now
        shutil.rmtree(self.path / SEGMENTS, ignore_errors=True)
        shutil.rmtree(staging, ignore_errors=True)


# ----------------------------------------------------------------------- reading
@dataclass
class Message:
    """One recorded message: topic, receive time (ns), the JSON object (String) or seconds (Clock)."""

    topic: str
    timestamp: int
    data: Any
    msgtype: str = STRING


@dataclass
class Recording:
    """A recording read back: its messages in time order, what it says of itself, what was lost."""

    path: Path
    messages: list[Message]
    custom: dict[str, str] = field(default_factory=dict)
    topics: dict[str, str] = field(default_factory=dict)  # name -> type
    counts: dict[str, int] = field(default_factory=dict)  # name -> messages
    lost: Optional[str] = None  # a cut-short recording: what is missing, in words
    undecodable: int = 0  # String messages whose data is not a JSON object (kept with data None)
    roles: dict[str, str] = field(default_factory=dict)  # topic name -> role (:data:`ROLES`)

    def on(self, role: str) -> list[Message]:
        """Return the messages of the topic(s) of ``role`` (:data:`ROLES`), in time order."""
        names = {name for name, r in self.roles.items() if r == role}
        return [m for m in self.messages if m.topic in names]

    def role(self, message: Message) -> Optional[str]:
        """Return the role of a message's topic (None: not an fsreg topic)."""
        return self.roles.get(message.topic)

    def attached(self, key: str) -> Optional[Path]:
        """Return the file attached as ``fsreg.<key>`` (None if the recording has none)."""
        name = self.custom.get(CUSTOM_PREFIX + key)
        return self.path / name if name else None


def open_recording(path: Path) -> Recording:
    """Read a recording (a rosbag2 folder, its ``.mcap`` file, or a folder cut short); RecordingError if it cannot.

    A folder without ``metadata.yaml`` but with closed segments was cut short: its segments
    are read and :attr:`Recording.lost` says which part is missing.
    """
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or folder")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        return _open_segments(path)
    messages, topics, custom, bad = _read_bag(path, path)
    return _recording(path, messages, topics, custom, bad)


def _recording(path: Path, messages: list[Message], topics: dict, custom: dict, bad: int,
               lost: Optional[str] = None) -> Recording:
    counts = {name: 0 for name in topics}
    for message in messages:
        counts[message.topic] = counts.get(message.topic, 0) + 1
    try:
        roles = json.loads(custom[TOPICS_KEY])
        if not isinstance(roles, dict):
            raise ValueError
    except (KeyError, ValueError):
        raise RecordingError(f"{path}: not an fsreg recording (its metadata's custom_data has no {TOPICS_KEY})") \
            from None
    return Recording(path if path.is_dir() else path.parent, messages, custom, topics, counts, lost, bad,
                     {str(k): str(v) for k, v in roles.items()})


def _open_segments(path: Path) -> Recording:
    folder = path / SEGMENTS
    segments = sorted(p for p in folder.iterdir() if p.is_dir()) if folder.is_dir() else []
    if not segments:
        raise RecordingError(f"{path}: not a recording (no metadata.yaml, no segments)")
    closed = [s for s in segments if (s / "metadata.yaml").exists()]
    open_ = [s for s in segments if s not in closed]
    messages: list[Message] = []
    topics: dict[str, str] = {}
    custom: dict[str, str] = {}
    bad = 0
    for segment in closed:
        got, seg_topics, seg_custom, seg_bad = _read_bag(segment, segment)
        messages += got
        topics.update(seg_topics)
        custom.update(seg_custom)
        bad += seg_bad
    if not closed:
        raise RecordingError(f"{path}: cut short before its first segment was closed: nothing can be recovered "
                             f"({', '.join(str(s) for s in open_)} has no index)")
    lost = None
    if open_:
        last = max((m.timestamp for m in messages), default=0)
        size = sum(f.stat().st_size for s in open_ for f in s.iterdir() if f.is_file())
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(last / 1e9)) if last else "the start"
        lost = (f"{path}: the recording was cut short (not closed): the messages after {when} "
                f"(wall clock) are lost, in {', '.join(s.name for s in open_)} ({size} bytes without an index); "
                f"{len(closed)} closed segment(s) with {len(messages)} messages are read")
    else:
        lost = (f"{path}: the recording was not closed (no metadata.yaml): its {len(closed)} segment(s) with "
                f"{len(messages)} messages are read; anything after the last one is lost")
    messages.sort(key=lambda m: m.timestamp)
    return _recording(path, messages, topics, custom, bad, lost)


def check_bag_files(path: Path) -> None:
    """Refuse a bag whose files are not regular files within their limits (RecordingError, one line).

    ``rosbags`` opens them by name: a ``metadata.yaml`` or ``.mcap`` that is a named pipe
    would block it forever, a link to ``/dev/zero`` would be read until memory runs out.
    So each is checked first (:mod:`fsreg_ros.core.io.input_file`), and ``metadata.yaml``'s
    size, depth and aliases as every YAML file's (:mod:`fsreg_ros.core.io.yaml_source`; its
    syntax is the library's to report).
    """
    from .input_file import InputFileError, check_file
    from .yaml_source import SourceError, check_structure, read_text

    try:
        if path.is_dir():
            metadata = path / "metadata.yaml"
            check_structure(read_text(metadata, limit=METADATA_MAX_BYTES), str(metadata))
            for storage in sorted(path.glob("*.mcap")):
                check_file(storage, MAX_BAG_BYTES)
        else:
            check_file(path, MAX_BAG_BYTES)
    except (InputFileError, SourceError) as err:
        where = err.source if getattr(err, "line", None) is None else f"{err.source}:{err.line}"
        raise RecordingError(f"{where}: not a readable recording ({err.message})") from None


def _read_bag(path: Path, name: Path) -> tuple[list[Message], dict[str, str], dict[str, str], int]:
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.errors import ReaderError

    check_bag_files(path)
    store = _typestore()
    messages: list[Message] = []
    bad = 0
    try:
        with Reader(path) as reader:
            topics = {c.topic: c.msgtype for c in reader.connections}
            metadata = getattr(getattr(reader, "storage", None), "metadata", None)
            custom = dict(getattr(metadata, "custom", None) or {})
            for connection, timestamp, raw in reader.messages():
                data, ok = _decode(store, connection.msgtype, raw)
                bad += 0 if ok else 1
                messages.append(Message(connection.topic, timestamp, data, connection.msgtype))
    except (ReaderError, FileNotFoundError, KeyError, ValueError, OSError, AssertionError, IndexError) as err:
        raise RecordingError(f"{_where(name, err)}: not a readable recording ({_one_line(err)})") from None
    except Exception as err:  # noqa: BLE001 - a damaged file can fail anywhere inside the library
        raise RecordingError(f"{_where(name, err)}: not a readable recording ({type(err).__name__}: "
                             f"{_one_line(err)})") from None
    return messages, topics, custom, bad


def _decode(store, msgtype: str, raw: bytes) -> tuple[Any, bool]:
    """Return (the message's content, whether it decoded): a JSON object, clock seconds, or None."""
    try:
        message = store.deserialize_cdr(raw, msgtype)
    except Exception:  # noqa: BLE001 - a damaged message: counted, kept as None
        return None, False
    if msgtype == CLOCK:
        return message.clock.sec + message.clock.nanosec / 1e9, True
    if msgtype == STRING:
        try:
            data = json.loads(message.data)
        except ValueError:
            return None, False
        return (data, True) if isinstance(data, dict) else (None, False)
    return None, True


def _where(path: Path, err: BaseException) -> str:
    """Return the file a reader error is about: the ``.mcap`` named in it if any, else the path."""
    text = str(err)
    if path.is_dir():
        for candidate in sorted(path.glob("*.mcap")):
            if candidate.name in text:
                return str(candidate)
        mcaps = sorted(path.glob("*.mcap"))
        if "metadata" in text.lower() or "yaml" in text.lower() or not mcaps:
            return str(path / "metadata.yaml")
        if len(mcaps) == 1:
            return str(mcaps[0])
    return str(path)


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split())[:300].rstrip(".") or type(err).__name__


def encode_string(data: dict) -> bytes:
    """Return a JSON object as the CDR bytes of a ``std_msgs/String`` (tests and tools that write bags)."""
    store = _typestore()
    return bytes(store.serialize_cdr(store.types[STRING](data=json.dumps(data, sort_keys=True)), STRING))


def encode_clock(seconds: float) -> bytes:
    """Return ``seconds`` as the CDR bytes of a ``rosgraph_msgs/Clock``."""
    store = _typestore()
    sec = int(seconds)
    stamp = store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((seconds - sec) * 1e9)))
    return bytes(store.serialize_cdr(store.types[CLOCK](clock=stamp), CLOCK))


def iter_json(messages: Iterable[Message]) -> Iterator[dict]:
    """Yield the JSON objects among ``messages``."""
    for message in messages:
        if isinstance(message.data, dict):
            yield message.data
