"""The rooms of gateway/ and stiction/ and what each may import (docs/architecture.md), read
from the code.

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
cli        all of the above (the simulator's commands arrive by entry point, never by import)
=========  ================================================================================

stiction/, from the bottom up (``_errors``, ``_assessment``, ``_validate`` are its ground):

==========  ===============================================================================
signal      the ground                        (arrays in, arrays out: no test, no verdict)
models      the ground                        (valves and the closed-loop simulator)
scenarios   models                            (data to test against: never a detector)
detectors   signal                            (one never imports another, but its own
                                               modules and ``base``; ``registry`` lists all)
quantify    signal                            (the sizes: never a detector's module)
diagnosis   detectors, quantify, signal
plant       diagnosis and everything below it (the plant-wide view)
paper       diagnosis, scenarios, models      (the paper's tables, reproduced)
cli         all of the above
==========  ===============================================================================

``stiction`` never imports ``gateway`` or ``plcsim``; ``plcsim`` uses the gateway's config
schema, errors, wire and runtime only; nothing in ``gateway`` imports ``plcsim``. Within a
room no modules import each other in a circle (not even for a type under TYPE_CHECKING).
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
GROUND = {"_errors", "_assessment", "_validate"}
STICTION_BELOW: dict[str, set[str]] = {
    "_errors": set(),
    "_assessment": set(),
    "_validate": {"_errors"},
    "signal": {"_validate", "_errors"},
    "models": GROUND,
    "scenarios": {"models", *GROUND},
    "detectors": {"signal", *GROUND},
    "quantify": {"signal", *GROUND},
    "diagnosis": {"detectors", "quantify", "signal", *GROUND},
    "plant": {"diagnosis", "detectors", "quantify", "signal", *GROUND},
    "paper": {"diagnosis", "scenarios", "models", "signal", *GROUND},
}
STICTION_BELOW["cli"] = set(STICTION_BELOW) - {"cli"}
STICTION_BELOW[""] = STICTION_BELOW["cli"]  # stiction/__init__: the public API
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


def imports(module: str, text: str, known: set[str]) -> Iterator[tuple[str, int]]:
    """(imported module, line) for each import of ``module``, wherever it stands."""
    package = module if module in PACKAGE_FACES else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                yield (sub if sub in known else base), node.lineno


def room(module: str) -> tuple[str, str]:
    """``gateway.inputs.modbus.client`` -> ("inputs", "modbus"); packages other than
    gateway are their own room."""
    parts = module.split(".")
    if parts[0] != "gateway":
        return parts[0], ""
    if len(parts) == 1:
        return "gateway", ""
    return parts[1], parts[2] if len(parts) > 2 else ""


def stiction_room(module: str) -> tuple[str, str]:
    """``stiction.detectors.kano`` -> ("detectors", "kano"); ``stiction`` -> ("", "")."""
    parts = module.split(".")[1:]
    return (parts[0] if parts else ""), (parts[1] if len(parts) > 1 else "")


def stiction_violation(target: str, here: tuple[str, str], there: tuple[str, str]
                       ) -> str | None:
    """Why ``here`` (a room of stiction and its part) may not import ``target``, or None."""
    top = target.split(".", maxsplit=1)[0]
    if top != "stiction":
        return f"stiction never imports {top}"
    (room_, part), (room_t, part_t) = here, there
    if room_ == room_t:
        if room_ == "detectors" and part not in ("", "base", "registry") and \
                part_t not in ("", "base", part):
            return f"detectors/{part} may not import detectors/{part_t} (one detector " \
                   "never imports another)"
        return None
    if room_t not in STICTION_BELOW.get(room_, set()):
        return f"{room_ or 'stiction'} may not import {room_t or 'stiction'} (a higher room " \
               "or a sibling)"
    return None


def violations(modules: Mapping[str, str]) -> list[str]:
    known = set(modules)
    found = []
    for module, text in sorted(modules.items()):
        here, plugin = room(module)
        for target, line in imports(module, text, known):
            there, other = room(target)
            if there not in (*PACKAGES, *BELOW) or target.split(".")[0] not in PACKAGES:
                continue  # the standard library or a third-party package
            where = f"{module}:{line} imports {target}"
            if here == "stiction":
                why = stiction_violation(target, stiction_room(module), stiction_room(target))
                if why:
                    found.append(f"{where}: {why}")
            elif here == "plcsim":
                if there not in ("plcsim", "stiction", "gateway", *PLCSIM_MAY_USE):
                    found.append(f"{where}: plcsim uses gateway's "
                                 f"{', '.join(sorted(PLCSIM_MAY_USE))} only")
            elif there == "plcsim":
                found.append(f"{where}: gateway never imports plcsim (its commands arrive by "
                             "entry point)")
            elif here in BELOW and there in BELOW and there != here \
                    and there not in BELOW[here]:
                found.append(f"{where}: {here} may not import {there} (a higher room or a "
                             f"sibling)")
            elif here == there and here in PLUGIN_ROOMS and plugin not in ("", "base") \
                    and other not in ("", "base", plugin):
                found.append(f"{where}: {here}/{plugin} may not import {here}/{other}")
    return found


def circles(modules: Mapping[str, str]) -> list[list[str]]:
    """Sets of modules that import each other in a circle (Tarjan's strongly connected
    components of the import graph, iteratively), each sorted."""
    known = set(modules)
    graph = {m: sorted({t for t, _ in imports(m, text, known) if t in known and t != m})
             for m, text in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            v, k = work.pop()
            if k == 0:
                index[v] = low[v] = len(index)
                stack.append(v)
                on.add(v)
            if k < len(graph[v]):
                work.append((v, k + 1))
                w = graph[v][k]
                if w not in index:
                    work.append((w, 0))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return found


SOURCES = sources()


def test_the_rooms_import_only_downward() -> None:
    modules = dict(SOURCES)
    assert {"gateway.core.points", "gateway.inputs.memory", "plcsim.sim",
            "stiction.detectors.registry", "stiction.diagnosis.evidence"} <= set(modules)
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
    ("stiction.models.valves", "from gateway.core.points import Quality",
     "stiction never imports gateway"),
    ("gateway.runtime.gateway", "import plcsim", "gateway never imports plcsim"),
    ("gateway.cli", "def main():\n    from plcsim.demo import run_demo\n",
     "gateway never imports plcsim"),
    ("stiction.detectors.kano", "from .horch import horch_test",
     "detectors/kano may not import detectors/horch"),
    ("stiction.detectors.hammerstein.search", "from ..stiction_index import stiction_index",
     "detectors/hammerstein may not import detectors/stiction_index"),
    ("stiction.detectors.ellipse", "from ..diagnosis.combine import confidence",
     "detectors may not import diagnosis"),
    ("stiction.models.valves", "from ..detectors.kano import kano_test",
     "models may not import detectors"),
    ("stiction.scenarios.realistic", "from stiction.detectors import registry",
     "scenarios may not import detectors"),
    ("stiction.scenarios.named", "from ..diagnosis.analyze import analyze",
     "scenarios may not import diagnosis"),
    ("stiction.signal.smooth", "from ..models.simulate import LoopBank",
     "signal may not import models"),
    ("stiction.quantify.route", "from ..detectors.ellipse import EllipseFit",
     "quantify may not import detectors"),
    ("stiction.diagnosis.combine", "from ..cli import main", "diagnosis may not import cli"),
    ("plcsim.sim", "from gateway.inputs.modbus import ModbusInput", "plcsim uses"),
])
def test_a_module_importing_upward_is_caught(module: str, text: str, why: str) -> None:
    modules = dict(SOURCES)
    modules[module] = text
    found = violations(modules)
    assert len(found) == 1 and why in found[0], found


def test_lazy_and_lower_imports_are_allowed() -> None:
    modules = dict(SOURCES)
    modules["stiction.detectors.kano"] = "from .base import Window\nfrom ..signal import cycle\n"
    modules["stiction.detectors.registry"] = "from . import kano, horch\n"
    modules["stiction.detectors.hammerstein.vote"] = "from .least_squares import rel\n"
    modules["gateway.inputs.modbus.client"] = ("from ..base import Source\n"
                                                "from ...core import points\n")
    modules["plcsim.demo"] = "from gateway.runtime.gateway import Gateway\n"
    assert violations(modules) == []


def test_no_modules_import_each_other_in_a_circle() -> None:
    assert circles(SOURCES) == []


def test_a_circle_is_caught() -> None:
    modules = dict(SOURCES)
    modules["gateway.core.points"] += "\nfrom .ticks import TickGrid\n"
    modules["gateway.core.ticks"] += "\nif TYPE_CHECKING:\n    from .points import Quality\n"
    assert ["gateway.core.points", "gateway.core.ticks"] in circles(modules)
