"""The lock (constraints.txt): a fresh clone installs exactly what the suite passed with.

Every dependency pyproject.toml names (runtime and every extra) is pinned, each pin inside
pyproject's range; under CI (a fresh install by `make test`) what is installed is what is
pinned, so a release of any dependency cannot change what CI or a new box runs.
"""

from __future__ import annotations

import os
import tomllib
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]


def _pins() -> dict[str, str]:
    pins: dict[str, str] = {}
    for raw in (REPO / "constraints.txt").read_text().splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, version = line.partition("==")
        assert sep and version and " " not in line, f"not an exact pin: {raw!r}"
        assert canonicalize_name(name) not in pins, f"pinned twice: {name}"
        pins[canonicalize_name(name)] = version
    return pins


def _requirements() -> list[Requirement]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    for extra in project["optional-dependencies"].values():
        reqs += [Requirement(r) for r in extra]
    return [r for r in reqs if canonicalize_name(r.name) != canonicalize_name(project["name"])]


def test_every_dependency_is_pinned_within_its_range() -> None:
    pins = _pins()
    for req in _requirements():
        version = pins.get(canonicalize_name(req.name))
        assert version is not None, f"{req.name} is not in constraints.txt (run make lock)"
        assert req.specifier.contains(version, prereleases=True), (
            f"{req.name}=={version} in constraints.txt is outside pyproject's {req}")


BOOTSTRAP = {"setuptools", "pip", "wheel"}
"""The venv's own tools: the interpreter's venv brings its own setuptools (65.5.0 on this
3.11), which the runtime install leaves; the bench extra's torch pulls the locked one."""


def test_under_ci_the_installed_versions_are_the_locked_ones() -> None:
    """`make test` installs with --constraint constraints.txt; CI runs it on a fresh clone."""
    if os.environ.get("CI") != "true":
        return  # a developer's venv may hold a newer release on purpose (make test-latest)
    wrong = []
    for name, version in _pins().items():
        if name in BOOTSTRAP:
            continue
        try:
            installed = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue  # pinned for an extra this environment does not install
        if installed != version:
            wrong.append(f"{name} {installed} (locked {version})")
    assert not wrong, "installed versions differ from constraints.txt: " + ", ".join(wrong)
