"""Reading a config file with bounded cost: what a hostile or broken file cannot do.

:func:`read_document` reads a YAML file for :func:`gateway.config.load_config`:

* at most :data:`MAX_CONFIG_BYTES` are read (a larger file is refused unread), from a
  regular file, within :data:`gateway.config.reading.READ_TIMEOUT_S` (a FIFO or a hung
  network mount is refused, never waited on);
* the bytes must be UTF-8 (a byte-order mark is allowed); a byte that is not is named with
  its line and column, e.g. a ``°`` saved as Latin-1 in a comment;
* before anything is built, one pass over the parser's events (no recursion, nothing kept
  but counts) refuses more than :data:`MAX_DEPTH` nested collections, :data:`MAX_ALIASES`
  aliases or :data:`MAX_NODES` nodes *after* expanding every alias (an "anchor bomb", a
  few lines that expand to billions of values, is refused in milliseconds);
* a key repeated in one mapping is refused (YAML keeps the last one silently: a second
  ``kp`` wins, a second ``loops:`` drops the first list); merge keys (``<<: *defaults``)
  may still be overridden.

Every error names the file and, where it helps, the line; none prints a value.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import yaml
from yaml import events

from ..errors import ConfigError
from .reading import read_bytes

__all__ = ["MAX_ALIASES", "MAX_CONFIG_BYTES", "MAX_DEPTH", "MAX_NODES", "read_document"]

MAX_CONFIG_BYTES = 8 * 1024 * 1024
"""A config file larger than this (8 MiB, about 50,000 loops) is refused."""
MAX_ALIASES = 100_000
"""Aliases (``*name``) in one file."""
MAX_NODES = 2_000_000
"""Scalars and collections in one file, every alias expanded (10,000 loops: ~300,000)."""
MAX_DEPTH = 64
"""Collections nested in each other (a config needs 5)."""

_BaseLoader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_MERGE = "tag:yaml.org,2002:merge"


def read_document(path: str | os.PathLike[str]) -> Any:
    """The YAML document of ``path``, within the limits above; ConfigError otherwise."""
    source = str(path)
    try:
        data = read_bytes(path, MAX_CONFIG_BYTES)  # a regular file, within a time limit
    except OSError as exc:
        raise ConfigError([f"{source}: cannot read: {exc.strerror or exc}"]) from None
    if len(data) > MAX_CONFIG_BYTES:
        raise ConfigError([f"{source}: the file is larger than {MAX_CONFIG_BYTES:,} bytes "
                           f"({MAX_CONFIG_BYTES // 2**20} MiB), the most a config may have"])
    text = decode(data, source)
    try:
        check_shape(text, source)
        loader = _Loader(text)
        try:
            document = loader.get_single_data()
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split()).replace(' in "<unicode string>",', " at")
        raise ConfigError([f"{source}: invalid YAML: {detail}"]) from None
    if loader.duplicates:
        raise ConfigError([f"{source}: {line}" for _at, line in sorted(loader.duplicates)])
    return document


def decode(data: bytes, source: str) -> str:
    """``data`` as UTF-8 text (a leading byte-order mark dropped); ConfigError naming the
    first byte that is not UTF-8, by line and column."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        start = exc.start
        line = data.count(b"\n", 0, start) + 1
        column = start - (data.rfind(b"\n", 0, start) + 1) + 1
        raise ConfigError([
            f"{source}: line {line}, column {column}: byte 0x{data[start]:02x} is not UTF-8 "
            "(the file was saved in another encoding, e.g. Latin-1 or Windows-1252: save "
            "it as UTF-8)"]) from None


def check_shape(text: str, source: str) -> None:
    """Refuse a document nested deeper than MAX_DEPTH, with more than MAX_ALIASES aliases
    or more than MAX_NODES nodes once its aliases are expanded, from its parser events
    (constant memory but for one count per anchor)."""
    sizes: dict[str, int] = {}  # anchor -> expanded size of its node
    open_: list[tuple[str | None, int]] = []  # (anchor, total when the collection began)
    total = aliases = 0
    for ev in _events(text, source):
        if isinstance(ev, events.AliasEvent):
            aliases += 1
            if aliases > MAX_ALIASES:
                _refuse(source, ev, f"more than {MAX_ALIASES:,} aliases")
            total += sizes.get(ev.anchor or "", 1)
        elif isinstance(ev, events.ScalarEvent):
            total += 1
            if ev.anchor is not None:
                sizes[ev.anchor] = 1
        elif isinstance(ev, events.CollectionStartEvent):
            total += 1
            open_.append((ev.anchor, total))
            if len(open_) > MAX_DEPTH:
                _refuse(source, ev, f"collections nested more than {MAX_DEPTH} deep")
        elif isinstance(ev, events.CollectionEndEvent) and open_:
            anchor, began = open_.pop()
            if anchor is not None:
                sizes[anchor] = total - began + 1
        if total > MAX_NODES:
            _refuse(source, ev, f"more than {MAX_NODES:,} values once its aliases are "
                    f"expanded ({aliases:,} aliases so far)")


def _events(text: str, source: str) -> Iterator[events.Event]:
    """The parser's events of ``text``. libyaml (PyYAML 6.0.4 and newer) has a nesting limit
    of its own that its scanner applies before the first event reaches the loop above: that
    refusal is reported as ours, so the message does not depend on the parser's version."""
    try:
        yield from yaml.parse(text, Loader=_BaseLoader)
    except yaml.MarkedYAMLError as exc:
        if "nesting depth" not in (exc.problem or ""):
            raise
        mark = exc.problem_mark
        where = f"line {mark.line + 1}: " if mark is not None else ""
        raise ConfigError([f"{source}: {where}the document has collections nested more "
                           f"than {MAX_DEPTH} deep; a config has far fewer (see "
                           "docs/reliability.md, config file limits)"]) from None


def _refuse(source: str, ev: events.Event, what: str) -> None:
    mark = ev.start_mark
    where = f"line {mark.line + 1}: " if mark is not None else ""
    raise ConfigError([f"{source}: {where}the document has {what}; a config has far "
                       "fewer (see docs/reliability.md, config file limits)"])


class _Loader(_BaseLoader):  # type: ignore[misc]
    """The safe loader, noting every key repeated within one mapping."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.duplicates: list[tuple[tuple[int, int], str]] = []  # ((line, column), text)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> Any:
        first: dict[tuple[str, str], str] = {}
        for key_node, _value in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE:
                continue
            key = (key_node.tag, key_node.value)
            mark = key_node.start_mark
            at = f"line {mark.line + 1}, column {mark.column + 1}"
            if key in first:
                self.duplicates.append(((mark.line, mark.column), (
                    f"{at}: key {_short(key_node.value)!r} repeats the key at {first[key]} "
                    "in the same mapping (YAML would silently keep only the last one)")))
            else:
                first[key] = at
        return super().construct_mapping(node, deep=deep)


def _short(text: str) -> str:
    return text if len(text) <= 40 else text[:37] + "..."

