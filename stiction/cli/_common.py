"""What the commands share: the usage error and option names."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeAlias

Handler = Callable[[argparse.Namespace], int]
if TYPE_CHECKING:
    Subparsers: TypeAlias = argparse._SubParsersAction[argparse.ArgumentParser]
else:  # not subscriptable at run time
    Subparsers = argparse._SubParsersAction


class UsageError(Exception):
    """Bad command-line input: printed as ``stiction: error: ...`` with exit status 2."""


def param_option(name: str) -> str:
    return "--" + name.replace("_", "-")


def pyplot() -> Any:
    try:  # optional dependency (the plot extra): imported only when a plot is asked for
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise UsageError("--plot needs matplotlib: pip install 'stiction-gateway[plot]'") from exc
    return plt
