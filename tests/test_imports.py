"""Every module of the engine and the app imports in the installed environment: a dependency that
is used but not declared in pyproject.toml fails here, not on a user's machine."""
import importlib
import pkgutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules(package: str) -> list[str]:
    found = [package]
    for info in pkgutil.walk_packages([str(ROOT / package)], prefix=f"{package}."):
        found.append(info.name)
    return sorted(found)


MODULES = _modules("engine") + _modules("app")


def test_the_walk_finds_the_tree():
    files = [p for pkg in ("engine", "app") for p in (ROOT / pkg).rglob("*.py")]
    assert len(MODULES) == len(files), "a folder without __init__.py hides its modules from the walk"


@pytest.mark.parametrize("name", MODULES)
def test_module_imports(name):
    importlib.import_module(name)
