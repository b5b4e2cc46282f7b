"""Files small enough to read in one sitting: no module over 400 lines and no class over 200
lines in gateway/ and plcsim/ (checked on the code, and on a too-long class to see it fail)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE, MAX_CLASS = 400, 200


def too_long(path: Path, text: str) -> list[str]:
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
    return found


def test_modules_and_classes_are_small() -> None:
    paths = sorted(p for pkg in ("gateway", "plcsim") for p in (ROOT / pkg).rglob("*.py"))
    assert len(paths) > 50
    found = [f for p in paths for f in too_long(p.relative_to(ROOT), p.read_text())]
    assert found == []


def test_a_long_class_is_caught() -> None:
    text = "class Big:\n" + "    x = 1\n" * MAX_CLASS
    assert too_long(Path("big.py"), text) == ["big.py: class Big 201 lines (at most 200)"]
    assert too_long(Path("long.py"), "x = 1\n" * 401) == ["long.py: 401 lines (at most 400)"]
