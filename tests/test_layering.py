"""The rooms of gateway/ and what each may import (docs/architecture.md), read from the code.

Every ``import`` statement (top level, inside functions, under TYPE_CHECKING) is resolved to
the module it names. From the bottom up:

=========  ================================================================================
errors     nothing of the gateway
wire       errors                            (what inputs, outputs and the simulator share)
config     wire, errors                      (never inputs: protocols are found by name)
core       config, errors                    (no IO: never inputs, outputs, runtime, wire)
inputs     core, config, wire, errors        (a protocol never imports another, nor outputs)
outputs    core, config, wire, errors        (a sink never imports another, nor inputs)
runtime    all of the above
cli        all of the above; plcsim only inside a function (loaded on demand)
=========  ================================================================================

``stiction`` never imports ``gateway`` or ``plcsim``; ``plcsim`` uses the gateway's config
schema, errors, wire and runtime only; nothing in ``gateway`` imports ``plcsim`` but the CLI.
The rules are checked on a few wrong modules first, so the test is seen to fail.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("gateway", "plcsim", "stiction")

BELOW: dict[str, set[str]] = {
    "errors": set(),
    "wire": {"errors"},
    "config": {"wire", "errors"},
    "core": {"config", "errors"},
    "inputs": {"core", "config", "wire", "errors"},
    "outputs": {"core", "config", "wire", "errors"},
    "runtime": {"inputs", "outputs", "core", "config", "wire", "errors"},
    "cli": {"runtime", "inputs", "outputs", "core", "config", "wire", "errors"},
}
PLCSIM_MAY_USE = {"config", "errors", "wire", "runtime"}
PLUGIN_ROOMS = ("inputs", "outputs")  # one folder per protocol / sink, plus base.py


PACKAGE_FACES = {".".join(p.relative_to(ROOT).parent.parts)
                 for pkg in PACKAGES for p in (ROOT / pkg).rglob("__init__.py")}


def sources() -> dict[str, str]:
    """Module name -> source text of every module of the three packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path.read_text(encoding="utf-8")
    return out


def imports(module: str, text: str, known: set[str]) -> Iterator[tuple[str, int, bool]]:
    """(imported module, line, inside a function) for each import of ``module``."""
    package = module if module in PACKAGE_FACES else module.rpartition(".")[0]
    tree = ast.parse(text)
    in_function: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            in_function.update(id(n) for n in ast.walk(node) if n is not node)
    for node in ast.walk(tree):
        nested = id(node) in in_function
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno, nested
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                yield (sub if sub in known else base), node.lineno, nested


def room(module: str) -> tuple[str, str]:
    """``gateway.inputs.modbus.client`` -> ("inputs", "modbus"); packages other than
    gateway are their own room."""
    parts = module.split(".")
    if parts[0] != "gateway":
        return parts[0], ""
    if len(parts) == 1:
        return "gateway", ""
    return parts[1], parts[2] if len(parts) > 2 else ""


def violations(modules: Mapping[str, str]) -> list[str]:
    known = set(modules)
    found = []
    for module, text in sorted(modules.items()):
        here, plugin = room(module)
        for target, line, nested in imports(module, text, known):
            there, other = room(target)
            if there not in (*PACKAGES, *BELOW) or target.split(".")[0] not in PACKAGES:
                continue  # the standard library or a third-party package
            where = f"{module}:{line} imports {target}"
            if here == "stiction":
                if target.split(".")[0] != "stiction":
                    found.append(f"{where}: stiction never imports {target.split('.')[0]}")
            elif here == "plcsim":
                if there not in ("plcsim", "stiction", "gateway", *PLCSIM_MAY_USE):
                    found.append(f"{where}: plcsim uses gateway's "
                                 f"{', '.join(sorted(PLCSIM_MAY_USE))} only")
            elif there == "plcsim":
                if not (here == "cli" and nested):
                    found.append(f"{where}: only the CLI loads plcsim, inside a function")
            elif here in BELOW and there in BELOW and there != here \
                    and there not in BELOW[here]:
                found.append(f"{where}: {here} may not import {there} (a higher room or a "
                             f"sibling)")
            elif here == there and here in PLUGIN_ROOMS and plugin not in ("", "base") \
                    and other not in ("", "base", plugin):
                found.append(f"{where}: {here}/{plugin} may not import {here}/{other}")
    return found


SOURCES = sources()


def test_the_rooms_import_only_downward() -> None:
    modules = dict(SOURCES)
    assert {"gateway.core.points", "gateway.inputs.memory", "plcsim.sim"} <= set(modules)
    assert violations(modules) == []


@pytest.mark.parametrize(("module", "text", "why"), [
    ("gateway.core.ticks", "from ..runtime.poller import DevicePoller",
     "core may not import runtime"),
    ("gateway.core.points", "import gateway.inputs.base", "core may not import inputs"),
    ("gateway.core.jobs", "from gateway.wire.codec import TYPES", "core may not import wire"),
    ("gateway.config.load", "from ..inputs.modbus import parse_device",
     "config may not import inputs"),
    ("gateway.inputs.modbus.client", "from ..opcua.errors import map_error",
     "inputs/modbus may not import inputs/opcua"),
    ("gateway.inputs.memory", "from ...outputs.memory import MemorySink",
     "inputs may not import outputs"),
    ("gateway.outputs.prometheus", "from ..statefile import StateFile",
     "outputs/prometheus may not import outputs/statefile"),
    ("gateway.wire.results", "from ..core.store import LoopResult",
     "wire may not import core"),
    ("stiction.valves", "from gateway.core.points import Quality",
     "stiction never imports gateway"),
    ("gateway.runtime.gateway", "import plcsim", "only the CLI loads plcsim"),
    ("gateway.cli", "from plcsim.demo import run_demo", "only the CLI loads plcsim, inside"),
    ("plcsim.sim", "from gateway.inputs.modbus import ModbusInput", "plcsim uses"),
])
def test_a_module_importing_upward_is_caught(module: str, text: str, why: str) -> None:
    modules = dict(SOURCES)
    modules[module] = text
    found = violations(modules)
    assert len(found) == 1 and why in found[0], found


def test_lazy_and_lower_imports_are_allowed() -> None:
    modules = dict(SOURCES)
    modules["gateway.cli"] = "def main():\n    import plcsim\n"
    modules["gateway.inputs.modbus.client"] = ("from ..base import Source\n"
                                                "from ...core import points\n")
    modules["plcsim.demo"] = "from gateway.runtime.gateway import Gateway\n"
    assert violations(modules) == []
