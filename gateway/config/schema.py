"""A tiny validating reader for YAML mappings that collects every problem at once.

``Section(problems, source, where, raw)`` wraps one mapping; ``req``/``opt`` read a key
(converting and checking it), and ``done()`` reports every key that was never read as
unknown, so a misspelt key is always an error. Each problem is one line::

    FILE: WHERE: key 'KEY': MESSAGE          (WHERE is e.g. "loop FIC101" or "gateway")

Protocol plugins (``gateway.inputs.<protocol>``) and the simulated PLC's config use the same
reader for their own keys: this is the one validator.
"""

from __future__ import annotations

import math
import re
import reprlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, TypeVar

__all__ = ["MISSING", "Problems", "Section", "boolean", "choice", "entries", "flag",
           "integer",
           "label_value", "listen_address", "mapping", "nonempty_list", "number", "number_pair",
           "string"]

T = TypeVar("T")


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


MISSING: Any = _Missing()


class Problems:
    """Collects problem lines; ``ok`` while none has been added."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.lines: list[str] = []

    def add(self, where: str, key: str | None, message: str) -> None:
        parts = [self.source, where] + ([f"key {key!r}"] if key else []) + [message]
        self.lines.append(": ".join(p for p in parts if p))

    @property
    def ok(self) -> bool:
        return not self.lines


def _type_name(value: Any) -> str:
    if value is None:
        return "null"
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "a list", dict: "a mapping"}.get(type(value), type(value).__name__)


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxtuple = 2, 4, 4, 4
_REPR.maxstring = _REPR.maxother = _REPR.maxlong = 40


def _describe(value: Any) -> str:
    """A short repr: never more than a few elements of a (maybe huge) collection."""
    text = _REPR.repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


class Section:
    """One mapping of the config file; keys are read with :meth:`req` / :meth:`opt`."""

    def __init__(self, problems: Problems, where: str, raw: Any, prefix: str = "") -> None:
        self.problems = problems
        self.where = where
        self.prefix = prefix  # "op." for nested point mappings, so keys read "op.type"
        self.valid = isinstance(raw, Mapping)
        self.raw: Mapping[str, Any] = raw if isinstance(raw, Mapping) else {}
        self._seen: dict[str, None] = {}  # keys read, in reading order
        self.origin = ""  # where the mapping was listed, if not the YAML ("loops.csv: line 4")
        if raw is not None and not self.valid:
            name = prefix.rstrip(".") or None
            problems.add(where, name, f"must be a mapping, was {_type_name(raw)}")

    def error(self, key: str | None, message: str) -> None:
        self.problems.add(self.where, None if key is None else self.prefix + key, message)

    def has(self, key: str) -> bool:
        return key in self.raw

    def sub(self, key: str, where: str | None = None) -> Section:
        """A nested mapping (missing → empty). Its keys are reported as ``key.sub`` in this
        section's ``where``, or as plain keys under a new ``where`` if one is given."""
        self._seen[key] = None
        if where is not None:
            return Section(self.problems, where, self.raw.get(key))
        return Section(self.problems, self.where, self.raw.get(key),
                       prefix=f"{self.prefix}{key}.")

    def raw_value(self, key: str) -> Any:
        self._seen[key] = None
        return self.raw.get(key, MISSING)

    def req(self, key: str, conv: Callable[[Any], T]) -> T | Any:
        """A required key; returns MISSING (after recording a problem) if absent or bad."""
        self._seen[key] = None
        if key not in self.raw:
            self.error(None, f"missing required key {self.prefix + key!r}")
            return MISSING
        return self._convert(key, self.raw[key], conv)

    def opt(self, key: str, conv: Callable[[Any], T], default: Any) -> T | Any:
        """An optional key with a default (used as is, not converted)."""
        self._seen[key] = None
        if key not in self.raw:
            return default
        return self._convert(key, self.raw[key], conv)

    def _convert(self, key: str, value: Any, conv: Callable[[Any], T]) -> T | Any:
        try:
            return conv(value)
        except (TypeError, ValueError) as exc:
            self.error(key, f"{exc}, was {_describe(value)}")
            return MISSING

    def done(self, *, list_known: bool = False) -> None:
        """Report every key that was not read as unknown (``list_known``: naming the keys
        that were read, in reading order, as the ones known)."""
        known = f" (known: {', '.join(self._seen)})" if list_known else ""
        for key in self.raw:
            if key not in self._seen:
                self.error(None, f"unknown key {self.prefix + str(key)!r}{known}")


# ---------------------------------------------------------------------------- converters
# Each raises TypeError/ValueError with a message that completes "key 'K': <message>, was V".


def string(value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise TypeError("must be a non-empty string")
    return value


def boolean(value: Any) -> bool:
    if not isinstance(value, bool):
        raise TypeError("must be true or false")
    return value


def flag(value: Any) -> bool:
    """true or false (a tag list's cell: true/false, yes/no, 1/0, any case)."""
    if isinstance(value, bool):
        return value
    words = {"true": True, "yes": True, "1": True, "false": False, "no": False, "0": False}
    if isinstance(value, str | int) and str(value).strip().lower() in words:
        return words[str(value).strip().lower()]
    raise TypeError("must be true or false")


def integer(lo: int | None = None, hi: int | None = None) -> Callable[[Any], int]:
    def conv(value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError("must be an integer")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise ValueError(f"must be in {lo}..{hi}" if hi is not None else f"must be >= {lo}")
        return value

    return conv


def number(*, positive: bool = False, non_negative: bool = False,
           at_most: float | None = None) -> Callable[[Any], float]:
    def conv(value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TypeError("must be a number")
        out = float(value)
        if not math.isfinite(out):
            raise ValueError("must be finite")
        if positive and out <= 0:
            raise ValueError("must be > 0")
        if non_negative and out < 0:
            raise ValueError("must be >= 0")
        if at_most is not None and out > at_most:
            raise ValueError(f"must be <= {at_most:g}")
        return out

    return conv


def choice(options: Sequence[str], hint: str = "") -> Callable[[Any], str]:
    def conv(value: Any) -> str:
        if value not in options:
            raise ValueError(f"must be one of {', '.join(options)}{hint}")
        return str(value)

    return conv


def listen_address(value: Any) -> tuple[str, int]:
    """``host:port`` (port 0 = any free port)."""
    if not isinstance(value, str) or ":" not in value:
        raise TypeError("must be 'host:port'")
    host, _, port = value.rpartition(":")
    host = host.strip("[]")
    if not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError("must be 'host:port' with a port in 0..65535")
    return host, int(port)


_LABEL_VALUE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def label_value(value: Any) -> str:
    """A name that becomes a metric label value (``gateway.site``, ``gateway.area``): 1-64
    letters, digits, ``_``, ``.`` or ``-``, starting with a letter or digit (safe in a
    Grafana regex selector and a file name)."""
    if not isinstance(value, str) or not _LABEL_VALUE.fullmatch(value):
        raise ValueError("must be 1-64 letters, digits, '_', '.' or '-', starting with a "
                         "letter or digit")
    return value


def entries(top: Section, key: str, label: str) -> Iterator[tuple[int, Any, Section]]:
    """``(index, name, section)`` for each mapping in the non-empty list ``key`` of ``top``,
    its problems named ``<label> <name>`` (``<key>[i]`` while it has no name); entries that
    are not mappings are reported and skipped."""
    raw_list = top.req(key, nonempty_list)
    for i, raw in enumerate(raw_list if raw_list is not MISSING else []):
        name = raw.get("name") if isinstance(raw, Mapping) else None
        where = f"{label} {name}" if isinstance(name, str) and name else f"{key}[{i}]"
        sec = Section(top.problems, where, raw)
        if sec.valid:
            yield i, name, sec


def nonempty_list(value: Any) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise TypeError("must be a non-empty list")
    return value


def mapping(value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TypeError("must be a mapping")
    return value


def number_pair(value: Any) -> tuple[float, float]:
    if (not isinstance(value, list | tuple) or len(value) != 2
            or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in value)):
        raise TypeError("must be a list of two numbers [lo, hi]")
    lo, hi = float(value[0]), float(value[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError("must be finite with hi > lo")
    return lo, hi
