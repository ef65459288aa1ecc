"""The fast YAML path gives exactly PyYAML's safe loader's values and the strict loader's errors."""

import gc
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from fsreg_ros.core.io.yaml_source import SourceError, collector_paused, load_yaml

DOCUMENTS = [
    "a: 1\nb: [x, 'y', 2.5, true, null, ~, 0x1F, 1_000, .inf, -.nan]\n",
    "e0001: [a00=v3, a01=v0]\ne0002: {a00=v1: 0.5, a01=v2: 1}\n",
    "base: &b {x: 1, y: 2}\nderived:\n  <<: *b\n  y: 3\n",  # merge key, overridden
    "shared: &s [1, 2]\nagain: *s\n",  # an alias: one shared list
    "when: 2020-01-02\nraw: !!binary aGVsbG8=\nset: !!set {a, b}\n",  # tags the fast path leaves alone
    "? [1, 2]\n: complex key\n",  # unhashable key: the general path's error
    "1: one\nfalse: no\nnull: nothing\n1.5: x\n",
    "- - - deep\n- []\n- {}\n",
    "plain scalar\n",
]


@pytest.mark.parametrize("text", DOCUMENTS)
def test_values_and_errors_equal_the_general_constructor(text):
    try:
        expected = ("value", yaml.load(text, Loader=yaml.CSafeLoader))
    except yaml.YAMLError as err:
        expected = ("error", type(err).__name__)
    try:
        _, value = load_yaml(text, "doc.yaml")
        got = ("value", value)
    except SourceError:
        got = ("error", "ConstructorError")
    if expected[0] == "value" and got[0] == "value":
        assert repr(got[1]) == repr(expected[1])  # repr: nan != nan
    else:
        assert got == expected


def test_an_alias_stays_one_shared_object():
    _, value = load_yaml("shared: &s [1, 2]\nagain: *s\n", "doc.yaml")
    assert value["again"] is value["shared"]


def test_a_recursive_alias_is_loaded_as_pyyaml_does():
    _, value = load_yaml("&r [1, *r]\n", "doc.yaml")
    assert value[1] is value


@pytest.mark.parametrize(
    "text, message",
    [
        ("a: 1\nb: 2\na: 3\n", "doc.yaml:3: a: duplicate key 'a' (first at line 1)"),
        ("top:\n  inner: {k: 1, k: 2}\n  k: 0\n", "doc.yaml:2: top.inner.k: duplicate key 'k' (first at line 2)"),
        ("a: 1\nb: !!int nope\n", "doc.yaml: not valid YAML: invalid literal for int() with base 10: 'nope'"),
    ],
)
def test_errors_name_the_place(text, message):
    with pytest.raises(SourceError) as caught:
        load_yaml(text, "doc.yaml")
    assert str(caught.value) == message


def test_the_collector_is_restored():
    assert gc.isenabled()
    with collector_paused():
        assert not gc.isenabled()
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
    assert gc.isenabled()
    with pytest.raises(SourceError):
        load_yaml("a: [\n", "doc.yaml")
    assert gc.isenabled()


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_path_that_is_not_a_regular_file_is_one_error_and_never_blocks(tmp_path, kind):
    """A named pipe nobody writes to would block a plain open() forever (issue 19, item 3)."""
    from fsreg_ros.core.io.yaml_source import read_yaml

    path = {"fifo": tmp_path / "pipe.yaml", "device": "/dev/zero", "directory": tmp_path}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    said = {"fifo": "is a named pipe (FIFO), not a regular file", "device": "is a character device, not a regular file",
            "directory": "is a directory, not a file"}[kind]
    with pytest.raises(SourceError) as caught:
        read_yaml(path)
    assert str(caught.value) == f"{path}: {said}"


@pytest.mark.parametrize("option", ["scenario", "--expect", "--lexicon"])
def test_fsreg_sim_refuses_a_fifo_in_one_line(tmp_path, table1_path, option):
    pipe = tmp_path / "pipe.yaml"
    os.mkfifo(pipe)
    args = [str(pipe)] if option == "scenario" else [str(table1_path), option, str(pipe)]
    proc = subprocess.run([str(Path(sys.executable).parent / "fsreg-sim"), *args], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == f"fsreg-sim: error: {pipe}: is a named pipe (FIFO), not a regular file\n"
