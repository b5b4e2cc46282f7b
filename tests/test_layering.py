"""The rooms of gateway/, stiction/ and lab/ and what each may import (docs/architecture.md),
read from the code.

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
valvetest   signal                            (step tests in manual: never the diagnosis)
ranking     diagnosis and everything below it (the list worst first, a site's calibration)
report      the ground                        (the maintenance meeting's page: HTML and SVG)
cli         all of the above
==========  ===============================================================================

lab/ (the corpus and the training), from the bottom up (``_types``, ``_cache`` its ground):

==========  ===============================================================================
sources     the ground                        (TEP runs, the realistic generator, the
                                               records, the named scenarios)
windows     sources                           (runs cut into views)
labels      windows, sources                  (each window's cause class; the corpus)
features    labels and everything below it    (the rows the decision reads)
training    features and everything below it  (the fit, the folds, the thresholds, reports)
export      training and everything below it  (model.json, weights.py)
commands    all of the above                  (python -m lab NAME; __main__ runs them)
==========  ===============================================================================

``stiction`` never imports ``gateway`` or ``plcsim``; ``plcsim`` uses the gateway's config
schema, errors, wire and runtime only; nothing in ``gateway`` imports ``plcsim``. ``lab``
and ``bench`` are development tooling: nothing of stiction, gateway or plcsim imports them;
``lab`` builds on ``stiction`` alone; ``bench`` may use everything. Within a room, and
anywhere in the five packages, no modules import each other in a circle (not even for a
type under TYPE_CHECKING).
The rules are checked on a few wrong modules first, so the test is seen to fail.
"""

from __future__ import annotations

import ast
import functools
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("gateway", "plcsim", "stiction", "lab", "bench")

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
    "valvetest": {"signal", *GROUND},
    "ranking": {"diagnosis", "detectors", "quantify", "signal", *GROUND},
    "report": {*GROUND},
}
STICTION_BELOW["cli"] = set(STICTION_BELOW) - {"cli"}
STICTION_BELOW[""] = STICTION_BELOW["cli"]  # stiction/__init__: the public API
PLUGIN_ROOMS = ("inputs", "outputs")  # one folder per protocol / sink, plus base.py
LAB_GROUND = {"_types", "_cache"}
LAB_ROOMS = ("sources", "windows", "labels", "features", "training", "export", "commands",
             "__main__")
MAY_IMPORT = {"stiction": {"stiction"}, "gateway": {"gateway", "stiction"},
              "plcsim": {"plcsim", "gateway", "stiction"}, "lab": {"lab", "stiction"},
              "bench": set(PACKAGES)}
"""The packages each package may import, where lab or bench is on either side."""


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


@functools.cache
def _import_nodes(text: str) -> tuple[ast.Import | ast.ImportFrom, ...]:
    """The import statements of ``text``, wherever they stand (each text parsed once: the
    rules are checked on the whole tree many times)."""
    return tuple(n for n in ast.walk(ast.parse(text)) if isinstance(n, ast.Import | ast.ImportFrom))


def imports(module: str, text: str, known: set[str]) -> Iterator[tuple[str, int]]:
    """(imported module, line) for each import of ``module``, wherever it stands."""
    package = module if module in PACKAGE_FACES else module.rpartition(".")[0]
    for node in _import_nodes(text):
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


def lab_room(module: str) -> str:
    """``lab.labels.corpus`` -> "labels"; ``lab`` -> ""."""
    return [*module.split("."), ""][1]


def lab_violation(here: str, there: str) -> str | None:
    """Why lab's room ``here`` may not import its room ``there`` (``""``: lab/__init__), or
    None: a room imports its own modules, the ground and the rooms below it."""
    below = LAB_ROOMS[:LAB_ROOMS.index(here)] if here in LAB_ROOMS else ()
    if there in (here, "", *below) or (there in LAB_GROUND and here not in LAB_GROUND):
        return None
    return f"lab/{here or '__init__'} may not import lab/{there} (a higher room or a sibling)"


def package_violation(module: str, target: str) -> str | None:
    """Why ``module`` may not import ``target`` where lab or bench is on either side."""
    top, other = module.partition(".")[0], target.partition(".")[0]
    if other not in MAY_IMPORT[top]:
        why = "development tooling, never the product's" if other in ("lab", "bench") \
            else "the lab builds on stiction alone"
        return f"{top} never imports {other} ({why})"
    if top == other == "lab":
        return lab_violation(lab_room(module), lab_room(target))
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
            if {"lab", "bench"} & {module.partition(".")[0], target.partition(".")[0]}:
                why = package_violation(module, target)
                if why:
                    found.append(f"{where}: {why}")
            elif here == "stiction":
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
            "stiction.detectors.registry", "stiction.diagnosis.evidence", "lab.sources.tep",
            "lab.labels.corpus", "lab.training.fit", "lab.export.model"} <= set(modules)
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
    ("stiction.valvetest.bands", "from ..diagnosis.analyze import analyze",
     "valvetest may not import diagnosis"),
    ("stiction.valvetest.response", "from ..scenarios.steptest import simulate_step_test",
     "valvetest may not import scenarios"),
    ("plcsim.sim", "from gateway.inputs.modbus import ModbusInput", "plcsim uses"),
    ("stiction.diagnosis.model", "from lab.export.model import MODEL",
     "stiction never imports lab"),
    ("gateway.runtime.scheduler", "def f():\n    import lab.features.rows\n",
     "gateway never imports lab"),
    ("plcsim.sim", "from bench._net import free_port", "plcsim never imports bench"),
    ("lab.labels.corpus", "from bench import real_data", "lab never imports bench"),
    ("lab.training.fit", "from gateway.core.store import ResultStore",
     "lab never imports gateway"),
    ("lab._types", "from .sources.tep import LOOPS", "lab/_types may not import lab/sources"),
    ("lab._cache", "from ._types import Window", "lab/_cache may not import lab/_types"),
    ("lab.sources.records", "from ..labels.rules import MIN_SLIPS",
     "lab/sources may not import lab/labels"),
    ("lab.windows.tep", "from ..features.rows import Row",
     "lab/windows may not import lab/features"),
    ("lab.labels.rules", "from ..training import fit", "lab/labels may not import lab/training"),
    ("lab.features.rows", "from lab.export.model import MODEL",
     "lab/features may not import lab/export"),
    ("lab.training.fit", "if TYPE_CHECKING:\n    from ..export.model import BY\n",
     "lab/training may not import lab/export"),
    ("lab.export.model", "from .. import commands", "lab/export may not import lab/commands"),
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
    modules["lab.export.model"] = ("from ..training.fit import Fitted\nfrom .._types import "
                                   "Window\nfrom ..sources import tep\nimport stiction\n")
    modules["lab.labels.corpus"] = "from .tep import tep_records\nfrom .. import _cache\n"
    modules["bench.accuracy.real_data"] = ("from lab.sources.records import Case\n"
                                  "from gateway.config import Config\nimport plcsim\n")
    assert violations(modules) == []


def test_no_modules_import_each_other_in_a_circle() -> None:
    assert {m.split(".")[0] for m in SOURCES} == set(PACKAGES)
    assert circles(SOURCES) == []


def test_a_circle_is_caught() -> None:
    modules = dict(SOURCES)
    modules["gateway.core.points"] += "\nfrom .ticks import TickGrid\n"
    modules["gateway.core.ticks"] += "\nif TYPE_CHECKING:\n    from .points import Quality\n"
    assert ["gateway.core.points", "gateway.core.ticks"] in circles(modules)


@pytest.mark.parametrize(("first", "second"), [
    # the benchmarks' old circle ran through an import inside a function
    ("bench.accuracy.real_data",
     "def corpus():\n    from bench.accuracy import corpus_baseline\n"),
    ("lab.labels.tep", "from .corpus import load_windows\n"),  # one room, still a circle
])
def test_a_circle_in_the_development_packages_is_caught(first: str, second: str) -> None:
    modules = dict(SOURCES)
    back = {"bench.accuracy.real_data": "bench.accuracy.corpus_baseline",
            "lab.labels.tep": "lab.labels.corpus"}
    modules[first] += "\n" + second
    modules["bench.accuracy.corpus_baseline"] += "\nfrom bench.accuracy.real_data import si_only\n"
    assert sorted([first, back[first]]) in circles(modules)
