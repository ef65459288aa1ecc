"""Recording fails like the rest of the tools (issue 37.8).

A folder name the file system refuses is one line naming the folder and the cause, exit 2,
from ``fsreg-ctl record`` and ``fsreg-up --record`` alike.  A disk that fills mid-recording
(simulated at the write layer: each write, then the final merge, refused with ENOSPC) stops
the recording with one error naming the cause; what was closed before stays readable by
``fsreg-plot``, the recording reader and the independent ``mcap`` reader; a recorder whose
writes fail closes without raising and keeps the error for its owner.
"""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fsreg_ros.core.io.recording import (
    CLOCK, STRING, TOPICS_KEY, BagWriter, Channel, RecordingError, WriteFailed, check_target, encode_clock,
    encode_string, open_recording,
)
from fsreg_ros.research.cli import plot_main
from fsreg_ros.tools import ctl, up

LONG = "r" * 300  # longer than any file system's NAME_MAX (255)
TOO_LONG = "cannot create it (File name too long)"


def test_a_folder_name_too_long_is_one_line_from_record_and_up(tmp_path, capsys, table1_path):
    folder = tmp_path / LONG
    with pytest.raises(RecordingError) as err:
        check_target(folder)
    assert str(err.value) == f"{folder}: {TOO_LONG}"
    assert ctl.main(["record", str(folder)]) == 2
    assert capsys.readouterr().err == f"fsreg-ctl: error: record: {folder}: {TOO_LONG}\n"
    assert up.main([str(table1_path), "--record", str(folder)]) == 2
    assert capsys.readouterr().err == f"fsreg-up: error: --record: {folder}: {TOO_LONG}\n"
    assert ctl.main(["record", str(tmp_path)]) == 2  # one that exists: as before
    assert capsys.readouterr().err == f"fsreg-ctl: error: record: {tmp_path} exists already; a recording goes to " \
                                      "a new folder\n"


class Ticks:
    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def full(*_args, **_kwargs) -> None:
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_disk_that_fills_stops_the_recording_and_keeps_what_was_closed(tmp_path, capsys):
    ticks, path = Ticks(), tmp_path / "bag"
    writer = BagWriter(path, [Channel("/r/wm/events", STRING, 100), Channel("/r/clock", CLOCK, 10)],
                       segment_seconds=1.0, now=ticks,
                       custom={TOPICS_KEY: json.dumps({"/r/wm/events": "events", "/r/clock": "clock"})})
    for seq in (1, 2):
        writer.write("/r/wm/events", seq, encode_string({"op": "encode", "domain": "faces", "entity": "face1",
                                                         "property": "male", "time": float(seq), "seq": seq}))
    writer.write("/r/clock", 3, encode_clock(2.0))
    ticks.ns = 2_000_000_000
    writer.poll()  # segment 0 closed: on disk, complete
    writer.write("/r/clock", 4, encode_clock(3.0))  # segment 1 open
    writer._writer.write = full  # the disk is full now
    with pytest.raises(WriteFailed) as err:
        writer.write("/r/clock", 5, encode_clock(4.0))
    assert str(err.value) == "No space left on device" and err.value.errno == errno.ENOSPC
    writer._merge = full  # and stays full while closing
    with pytest.raises(WriteFailed) as err:
        writer.close()
    assert str(err.value) == "No space left on device"
    recording = open_recording(path)  # the closed segment, read as a recording cut short
    assert [m.data for m in recording.on("clock")] == [2.0, 3.0]  # everything written before the disk filled
    assert [m.data["seq"] for m in recording.on("events")] == [1, 2]
    assert recording.lost is not None and "not closed" in recording.lost
    assert not (path / ".merge").exists()
    segment = sorted((path / "segments").glob("*/*.mcap"))[0]
    with segment.open("rb") as handle:  # the independent reader
        assert sum(1 for _ in make_reader(handle).iter_messages()) == 3
    assert plot_main([str(path), "-o", str(tmp_path / "wm.png")]) == 0
    assert (tmp_path / "wm.png").stat().st_size > 0


@pytest.mark.graph
def test_a_recorder_whose_disk_fills_closes_without_raising_and_keeps_the_cause(tmp_path):
    from fsreg_ros import contract
    from fsreg_ros.ros.recorder import Recorder
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession("/full") as session:
        recorder = Recorder(session.probe, tmp_path / "bag")
        recorder.bag._writer_class = _FullWriter  # every segment's writes are refused
        answer = {"id": "r1", "resolved": "face1"}
        session.publish("/full/rr/result", answer, contract.PIPELINE_QOS)  # the writer (matched or not yet)
        session.spin_until(lambda: recorder.matched()["/full/rr/result"] >= 1, 10.0, what="the recorder matched")
        session.publish("/full/rr/result", answer, contract.PIPELINE_QOS)
        session.spin_until(lambda: recorder.error is not None, 10.0, what="the recorder's thread to stop")
        session.publish("/full/rr/result", answer, contract.PIPELINE_QOS)  # more comes: not written, not raised
        assert recorder.close() == tmp_path / "bag"
    assert isinstance(recorder.error, WriteFailed) and str(recorder.error) == "No space left on device"
    assert not (tmp_path / "bag" / "metadata.yaml").exists()


class _FullWriter:
    """A rosbags writer on a full disk: opening works, every write and close is refused."""

    def __init__(self, path: Path, **_kwargs) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self._real = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.path = path

    def open(self) -> None:
        self._real.open()

    def add_connection(self, *args, **kwargs):
        return self._real.add_connection(*args, **kwargs)

    def set_custom_data(self, *args) -> None:
        self._real.set_custom_data(*args)

    write = close = staticmethod(full)
