"""`stiction`: offline tools (simulate, signature, analyze, plant, reproduce, valve-test).

Exit status: 0 success, 2 bad arguments or unusable input (the message names the problem).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence

from .._errors import ParameterError, StictionError
from ._common import Handler, Subparsers, UsageError, param_option
from .analyze import add_analyze
from .plant import add_plant
from .reproduce import add_reproduce
from .simulate import add_signature, add_simulate
from .valvetest import add_valve_test

__all__ = ["build_parser", "main"]

# ---------------------------------------------------------------------------------- main
_COMMANDS: list[Callable[[Subparsers], None]] = [
    add_simulate,
    add_signature,
    add_analyze,
    add_plant,
    add_reproduce,
    add_valve_test,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="stiction", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler = args.handler
    try:
        return handler(args)
    except BrokenPipeError:  # `stiction analyze ... | head`: the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush is quiet
        return 1
    except ParameterError as exc:
        parser.exit(2, f"stiction: error: {param_option(exc.name)}: {exc}\n")
    except (UsageError, StictionError) as exc:
        parser.exit(2, f"stiction: error: {exc}\n")
    return 0  # pragma: no cover
