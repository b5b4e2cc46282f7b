"""The package's exception root.

Every error the library raises on bad input is a :class:`StictionError`; the ones about
an argument's value also derive from :class:`ValueError`, as scipy's do, and name the
argument in the message and in :attr:`ParameterError.name`.
"""

from __future__ import annotations

__all__ = ["ParameterError", "StictionError"]


class StictionError(Exception):
    """Root of every exception raised by :mod:`stiction`."""


class ParameterError(StictionError, ValueError):
    """An argument has a value the library cannot use.

    ``name`` is the argument's name as the caller spelt it, so a CLI can map it back
    to its own option (``fs`` -> ``--fs``).
    """

    def __init__(self, name: str, message: str) -> None:
        super().__init__(f"`{name}` {message}")
        self.name = name
