"""Reading fsreg's YAML files (scenarios, KBs, lexicons, expected tables): one strict loader.

Every file is read the same way:

1. :func:`read_text` reads it as UTF-8 text through :mod:`fsreg_ros.core.io.input_file`; a
   missing file, a directory or anything else that is not a regular file (a named pipe,
   which would block the reader until a writer came, a device), an unreadable or
   oversized file, a NUL byte or invalid UTF-8 is one :class:`SourceError` naming the file.
   Its structure is checked before a tree is built (:func:`check_structure`: nesting
   depth, aliases expanded).
2. :func:`load_yaml` parses it with libyaml's C parser (:class:`FastLoader`) and
   keeps the node tree, whose nodes carry their line, so a path inside the
   document (``dialogue[3].text``) can be mapped to a line (:func:`find_line`).
   Mapping keys may not repeat (a duplicate is an error, not "the last wins"); a
   ``<<`` merge key may be overridden.  Only when the C parser reports an error is
   the text parsed again by the pure-Python parser (:class:`ExactLoader`, same
   rules), whose messages are the more precise ones.

Speed (a generated world of 10,000 entities is ~400,000 nodes): while the node
tree is built and converted, Python's cyclic garbage collector is paused (it
would otherwise rescan the growing tree over and over: x3 on the whole load;
the tree holds no cycles it would have to free), and plain nodes -- strings,
numbers, booleans, nulls, lists and mappings, which is all a scenario uses --
are converted by :func:`_plain_value` instead of PyYAML's general constructor.
Anything else (an anchor used twice, a ``<<`` merge, a tag such as a timestamp or
``!!set``) sends the whole document to the general constructor, so the result is
always exactly PyYAML's safe loader's.
"""

from __future__ import annotations

import gc
import operator
import os
import types
from contextlib import contextmanager
from operator import attrgetter
from typing import Any, Iterator, Optional, Sequence, Union

import yaml

from . import input_file
from .input_file import MAX_FILE_BYTES

#: Deepest nesting of collections a YAML file may have (fsreg's own nest under 10 deep).
MAX_DEPTH = 1000
#: Nodes a document's aliases may add, counted expanded (an alias of a list of 10 lists of 10 adds 111).
MAX_ALIAS_NODES = 1_000_000

PathLoc = tuple[Union[str, int], ...]


class SourceError(ValueError):
    """One problem with an input file: where it is and what is wrong.

    ``str(err)`` is one line, ``"{source}:{line}: {path}: {message}"``, without
    ``:{line}`` when the line is unknown and without ``{path}: `` when the problem
    concerns the whole file (``path == ""``).
    """

    def __init__(self, source: str, path: str, message: str, line: Optional[int] = None) -> None:
        self.source = source
        self.path = path
        self.message = message
        self.line = line
        super().__init__(self._format())

    def _format(self) -> str:
        where = self.source if self.line is None else f"{self.source}:{self.line}"
        return f"{where}: {self.path}: {self.message}" if self.path else f"{where}: {self.message}"

    def __str__(self) -> str:
        return self._format()

    def __reduce__(self) -> tuple:
        # Picklable (e.g. across processes) despite the custom constructor.
        return (type(self), (self.source, self.path, self.message, self.line))


class DuplicateKeyError(yaml.YAMLError):
    """A mapping names the same key twice."""

    def __init__(self, mapping: yaml.MappingNode, key: Any, first: yaml.Node, second: yaml.Node) -> None:
        super().__init__(f"duplicate key {key!r}")
        self.mapping, self.key, self.first, self.second = mapping, key, first, second


class StrictConstruction:
    """Construction rules shared by both loaders: no duplicate mapping keys.

    ``<<`` merge keys are skipped by the check: merged values may be overridden.
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        """Return the mapping of ``node``; raise DuplicateKeyError if a key repeats."""
        seen: dict[Any, yaml.Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)  # type: ignore[attr-defined]
            try:
                first = seen.get(key)
            except TypeError:
                continue  # unhashable: SafeConstructor reports it
            if first is not None:
                raise DuplicateKeyError(node, key, first, key_node)
            seen[key] = key_node
        return super().construct_mapping(node, deep=deep)  # type: ignore[misc]


class ExactLoader(StrictConstruction, yaml.SafeLoader):
    """The pure-Python strict loader: used to explain an error the C parser found."""


_ScalarNode = yaml.ScalarNode


class FastLoader(StrictConstruction, getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """The strict loader on libyaml's C parser (the pure-Python one if libyaml is missing).

    The tag of a plain scalar depends on its text alone (no path resolvers are
    registered), so it is looked up once per distinct text: a world repeats the
    same property names hundreds of thousands of times.  The parser calls
    :meth:`resolve` for every scalar (400,000 in a world of 10,000 entities), so the
    cached case is kept to one type test and one dictionary lookup.
    """

    # The composer calls these path-resolver hooks around every node.  With no path
    # resolver registered (fsreg registers none) PyYAML's return at once, but each is
    # still a Python call (2 x 400,000 in a world of 10,000 entities): C-level no-ops
    # stand in for them, unless a path resolver is registered after all (__init__).
    descend_resolver = staticmethod(operator.is_)
    ascend_resolver = staticmethod(tuple)

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._plain_tags: dict[str, str] = {}
        self._cache_plain = not self.yaml_path_resolvers  # a path resolver makes a tag depend on the place
        if self.yaml_path_resolvers:
            self.descend_resolver = types.MethodType(yaml.resolver.BaseResolver.descend_resolver, self)
            self.ascend_resolver = types.MethodType(yaml.resolver.BaseResolver.ascend_resolver, self)

    def resolve(self, kind: type, value: Any, implicit: Any) -> str:
        """Return the tag of a node, as the safe loader's resolver would."""
        if kind is _ScalarNode and implicit[0] and self._cache_plain:
            try:
                return self._plain_tags[value]
            except KeyError:
                tag = self._plain_tags[value] = super().resolve(kind, value, implicit)
                return tag
        return super().resolve(kind, value, implicit)


def read_text(path: Union[str, os.PathLike], error: type[SourceError] = SourceError,
              limit: Optional[int] = None) -> str:
    """Return the text of ``path``; raise ``error`` naming the file if it cannot be text.

    The file is opened without blocking and must be a regular file of at most ``limit``
    bytes (default :data:`MAX_FILE_BYTES`, read when called; :mod:`fsreg_ros.core.io.input_file`):
    reading a named pipe would wait for a writer forever, a device would never end.
    """
    try:
        return input_file.read_text(path, MAX_FILE_BYTES if limit is None else limit)
    except input_file.InputFileError as err:
        raise error(err.source, "", err.message) from None


def check_structure(text: str, source: str, error: type[SourceError] = SourceError) -> None:
    """Refuse YAML nested deeper than :data:`MAX_DEPTH` or whose aliases expand to over :data:`MAX_ALIAS_NODES` nodes.

    Checked on the parser's events before any node tree is built (libyaml's composer
    recurses once per level in C, and a few ten thousand levels crash the process; an
    alias bomb is small as a tree but explodes in whatever walks it).  A text that can
    be neither -- no ``*`` and fewer brackets and columns than :data:`MAX_DEPTH` allows,
    as any ordinary file -- is not parsed twice.  A syntax error is left to the loader,
    whose message is the precise one.
    """
    longest = max(map(len, text.splitlines()), default=0)
    if "*" not in text and text.count("[") + text.count("{") + 2 * longest + 2 <= MAX_DEPTH:
        return  # a block node's column grows with its depth (2 levels a column at most), a flow one needs a bracket
    parser = FastLoader(text)
    starts: list[tuple[Optional[str], int]] = []  # each open collection: its anchor, the node count at its start
    sizes: dict[str, int] = {}  # anchor -> nodes of its node, aliases expanded
    nodes = aliased = 0
    try:
        while True:
            event = parser.get_event()
            if event is None or isinstance(event, yaml.StreamEndEvent):
                return
            if isinstance(event, yaml.AliasEvent):
                size = sizes.get(event.anchor, 1)
                nodes += size
                aliased += size
                if aliased > MAX_ALIAS_NODES:
                    raise error(source, "", f"not valid here: its aliases expand to over {MAX_ALIAS_NODES:,} "
                                f"nodes (an alias bomb?)", event.start_mark.line + 1)
            elif isinstance(event, yaml.ScalarEvent):
                nodes += 1
                if event.anchor is not None:
                    sizes[event.anchor] = 1
            elif isinstance(event, yaml.CollectionStartEvent):
                nodes += 1
                starts.append((event.anchor, nodes))
                if len(starts) > MAX_DEPTH:
                    raise error(source, "", f"not valid here: YAML nested deeper than {MAX_DEPTH} levels",
                                event.start_mark.line + 1)
            elif isinstance(event, yaml.CollectionEndEvent):
                anchor, start = starts.pop()
                if anchor is not None:
                    sizes[anchor] = nodes - start + 1
    except yaml.YAMLError:
        return  # the loader reports it, with its place
    finally:
        parser.dispose()


def load_yaml(text: str, source: str, error: type[SourceError] = SourceError) -> tuple[Optional[yaml.Node], Any]:
    """Return the single document's root node (None if empty) and its value.

    Its depth and aliases are checked first (:func:`check_structure`); then it is parsed
    with :class:`FastLoader`; on any error the text is parsed again with
    :class:`ExactLoader` and its error becomes one ``error`` with path and line.
    """
    check_structure(text, source, error)
    try:
        return _load(FastLoader, text)
    except _LOAD_ERRORS:
        pass
    try:
        result = _load(ExactLoader, text, keep=True)
    except _Failed as failed:
        raise _yaml_problem(failed.err, failed.root, source, error) from None
    return result  # pragma: no cover - both parsers agree on valid YAML


#: What parsing and construction raise for bad input (a bad explicit tag such as
#: ``!!int nope`` is a ValueError from PyYAML's constructor).
_LOAD_ERRORS = (yaml.YAMLError, RecursionError, ValueError, TypeError, OverflowError)


class _Failed(Exception):
    def __init__(self, err: BaseException, root: Optional[yaml.Node]) -> None:
        super().__init__(str(err))
        self.err, self.root = err, root


def _load(loader_class: type, text: str, keep: bool = False) -> tuple[Optional[yaml.Node], Any]:
    loader = loader_class(text)
    root: Optional[yaml.Node] = None
    try:
        with collector_paused():
            root = loader.get_single_node()
            return root, (_construct(loader, root) if root is not None else None)
    except _LOAD_ERRORS as err:
        if keep:
            raise _Failed(err, root) from None
        raise
    finally:
        loader.dispose()


@contextmanager
def collector_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector for a bulk build of (mostly) acyclic objects.

    A collection while it is paused would rescan the growing structure over and
    over.  Release what is not kept before the block ends: the first collection
    afterwards scans whatever survives.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


#: The tags :func:`_plain_value` converts itself.
_STR, _SEQ, _MAP = "tag:yaml.org,2002:str", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:map"
_SCALARS = {
    "tag:yaml.org,2002:int": yaml.constructor.SafeConstructor.construct_yaml_int,
    "tag:yaml.org,2002:float": yaml.constructor.SafeConstructor.construct_yaml_float,
    "tag:yaml.org,2002:bool": yaml.constructor.SafeConstructor.construct_yaml_bool,
    "tag:yaml.org,2002:null": yaml.constructor.SafeConstructor.construct_yaml_null,
}


_SCALAR_ONLY, _STR_ONLY = frozenset((yaml.ScalarNode,)), frozenset((_STR,))
_tag_of, _value_of = attrgetter("tag"), attrgetter("value")


class _NotPlain(Exception):
    """The document uses more of YAML than :func:`_plain_value` converts."""


def _construct(loader: Any, root: yaml.Node) -> Any:
    """Return the value of the document ``root``, exactly as ``loader.construct_document`` would."""
    try:
        return _plain_value(loader, root, set())
    except Exception:  # _NotPlain, or an error: the general constructor decides (and reports) exactly
        return loader.construct_document(root)


def _plain_value(loader: Any, node: yaml.Node, seen: set[int]) -> Any:
    """Convert a tree of plain nodes; raise _NotPlain on anything else.

    ``seen`` holds the ids of the collections converted so far: one met twice is an
    alias, which the general constructor turns into one shared object.  A repeated
    key is left to the general constructor too, which reports the first one in its
    own order (:class:`StrictConstruction`).
    """
    tag = node.tag
    if tag == _STR:
        if type(node) is not yaml.ScalarNode:
            raise _NotPlain
        return node.value
    if tag == _SEQ or tag == _MAP:
        if id(node) in seen:
            raise _NotPlain
        seen.add(id(node))
        if tag == _SEQ:
            if type(node) is not yaml.SequenceNode:
                raise _NotPlain
            items = node.value
            if _SCALAR_ONLY.issuperset(map(type, items)) and _STR_ONLY.issuperset(map(_tag_of, items)):
                return list(map(_value_of, items))  # a list of strings (a world's facts): C-level passes
            return [
                item.value if item.tag == _STR and type(item) is yaml.ScalarNode else _plain_value(loader, item, seen)
                for item in items
            ]
        if type(node) is not yaml.MappingNode:
            raise _NotPlain
        out: dict = {}
        for key_node, value_node in node.value:
            if type(key_node) is not yaml.ScalarNode:
                raise _NotPlain  # a collection as a key (unhashable, or a merge): the general path reports it
            key = _plain_value(loader, key_node, seen)
            if key in out:
                raise _NotPlain
            out[key] = _plain_value(loader, value_node, seen)
        return out
    convert = _SCALARS.get(tag)
    if convert is None or type(node) is not yaml.ScalarNode:
        raise _NotPlain
    return convert(loader, node)


def _yaml_problem(err: BaseException, root: Optional[yaml.Node], source: str, error: type[SourceError]) -> SourceError:
    if isinstance(err, DuplicateKeyError):
        loc = (path_to(root, err.mapping) or ()) if root is not None else ()
        loc += (str(err.key),)
        message = f"duplicate key '{err.key}' (first at line {node_line(err.first)})"
        return error(source, render_path(loc), message, node_line(err.second))
    if isinstance(err, RecursionError):
        return error(source, "", "not valid here: YAML nested too deeply")
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        problem = err.problem or err.context or "syntax error"
        if err.context and err.problem:
            started = f" started at line {err.context_mark.line + 1}" if err.context_mark else ""
            problem += f" ({err.context}{started})"
        return error(source, "", f"not valid YAML: {problem}", mark.line + 1 if mark else None)
    return error(source, "", f"not valid YAML: {' '.join(str(err).split())}")


def node_line(node: yaml.Node) -> int:
    """Return the 1-based line where ``node`` starts."""
    return node.start_mark.line + 1


def find_line(root: Optional[yaml.Node], loc: PathLoc) -> tuple[Optional[int], bool]:
    """Return the line of the node at ``loc`` and whether the whole path was found.

    The line is that of the mapping key for a mapping entry; when the path is not
    found, the line of the deepest node found.
    """
    node, line = root, (node_line(root) if root is not None else None)
    for segment in loc:
        found = None
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                if isinstance(key_node, yaml.ScalarNode) and key_node.value == str(segment):
                    found, line = value_node, node_line(key_node)
                    break
        elif isinstance(node, yaml.SequenceNode) and isinstance(segment, int) and 0 <= segment < len(node.value):
            found = node.value[segment]
            line = node_line(found)
        if found is None:
            return line, False
        node = found
    return line, True


def path_to(root: yaml.Node, target: yaml.Node) -> Optional[PathLoc]:
    """Return the path from ``root`` to the node ``target`` (by identity), or None."""
    stack: list[tuple[yaml.Node, PathLoc]] = [(root, ())]
    seen: set[int] = set()
    while stack:
        node, loc = stack.pop()
        if node is target:
            return loc
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                key = key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"
                stack.append((value_node, loc + (key,)))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, loc + (i,)) for i, item in enumerate(node.value))
    return None


def render_path(loc: Sequence[Union[str, int]]) -> str:
    """Return ``("dialogue", 3, "description", 1)`` as ``"dialogue[3].description[1]"``."""
    out = ""
    for segment in loc:
        if isinstance(segment, int) and not isinstance(segment, bool):
            out += f"[{segment}]"
        else:
            out += f".{segment}" if out else str(segment)
    return out


def read_yaml(path: Union[str, os.PathLike], error: type[SourceError] = SourceError,
              limit: Optional[int] = None) -> tuple[Optional[yaml.Node], Any]:
    """Return the root node and value of the YAML file ``path`` of at most ``limit`` bytes (see :func:`load_yaml`)."""
    return load_yaml(read_text(path, error, limit), os.fspath(path), error)


def describe_value(value: Any) -> str:
    """Return a short description of a wrong value, for messages."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return (
            f"the boolean {str(value).lower()} "
            "(YAML reads yes/no/on/off/true/false as booleans; quote it if you mean text)"
        )
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return f"a {type(value).__name__}"


__all__ = [
    "MAX_ALIAS_NODES",
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "check_structure",
    "DuplicateKeyError",
    "ExactLoader",
    "FastLoader",
    "collector_paused",
    "SourceError",
    "describe_value",
    "find_line",
    "load_yaml",
    "node_line",
    "path_to",
    "read_text",
    "read_yaml",
    "render_path",
]
