"""Files small enough to read in one sitting: no module over 400 lines and no class over 200
lines in gateway/, plcsim/, stiction/ and lab/, no function over 80 lines in stiction/, and no
more than a handful of modules at stiction/'s top level (checked on the code, and on
too-long pieces to see it fail)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE, MAX_CLASS, MAX_FUNCTION = 400, 200, 80
STICTION_TOP = {"__init__.py", "_assessment.py", "_errors.py", "_validate.py"}
"""The public API, the public types and the argument checks; everything else has a room."""


def too_long(path: Path, text: str, *, functions: bool = False) -> list[str]:
    found = []
    lines = len(text.splitlines())
    if lines > MAX_MODULE:
        found.append(f"{path}: {lines} lines (at most {MAX_MODULE})")
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ClassDef):
            start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            size = (node.end_lineno or start) - start + 1
            if size > MAX_CLASS:
                found.append(f"{path}: class {node.name} {size} lines (at most {MAX_CLASS})")
        elif functions and isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            size = (node.end_lineno or start) - start + 1
            if size > MAX_FUNCTION:
                found.append(f"{path}: function {node.name} {size} lines "
                             f"(at most {MAX_FUNCTION})")
    return found


def test_modules_classes_and_functions_are_small() -> None:
    paths = sorted(p for pkg in ("gateway", "plcsim", "stiction", "lab")
                   for p in (ROOT / pkg).rglob("*.py"))
    assert len(paths) > 100
    found = [f for p in paths for f in too_long(
        p.relative_to(ROOT), p.read_text(), functions=p.relative_to(ROOT).parts[0] == "stiction")]
    assert found == []


def test_stiction_keeps_few_modules_at_its_top_level() -> None:
    top = {p.name for p in (ROOT / "stiction").glob("*.py")}
    assert top == STICTION_TOP


def test_a_long_class_is_caught() -> None:
    text = "class Big:\n" + "    x = 1\n" * MAX_CLASS
    assert too_long(Path("big.py"), text) == ["big.py: class Big 201 lines (at most 200)"]
    assert too_long(Path("long.py"), "x = 1\n" * 401) == ["long.py: 401 lines (at most 400)"]
    body = "def f():\n" + "    x = 1\n" * MAX_FUNCTION
    assert too_long(Path("f.py"), body, functions=True) == [
        "f.py: function f 81 lines (at most 80)"]
    assert too_long(Path("f.py"), body) == []
