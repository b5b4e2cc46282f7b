"""The package's face: ``gateway.__all__`` names its public API, every name is importable
from ``gateway`` and documented, and ``import gateway`` alone loads none of the rooms."""

from __future__ import annotations

import subprocess
import sys

import gateway


def test_every_public_name_is_there_and_documented() -> None:
    assert "__version__" in gateway.__all__ and gateway.__version__ == "0.1.0"
    for name in gateway.__all__:
        if name == "__version__":
            continue
        obj = getattr(gateway, name)
        assert (obj.__doc__ or "").strip(), f"gateway.{name} has no docstring"
        assert name in (gateway.__doc__ or ""), f"gateway.{name} is not in the package docs"
    assert sorted(dir(gateway)) == sorted(gateway.__all__)


def test_importing_the_package_loads_nothing_else() -> None:
    code = ("import sys, gateway; "
            "print(sorted(m for m in sys.modules if m.startswith(('gateway.', 'plcsim'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60).stdout
    assert out.strip() == "['gateway._version']"
