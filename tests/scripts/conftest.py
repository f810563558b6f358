"""Tests of the repository's research scripts (scripts/*.py), which use the package `pino_mbd`
but are not part of it. They run on the package tests' tiny quarter-car pipeline (the fixtures
`run` and `quarter_car` of python/tests/conftest.py, loaded from there: with
``PINO_TEST_WORKSPACE`` set, as ``scripts/test`` sets it, the run is the one python/tests made).
Run them with ``pytest tests/scripts`` in an environment where ``pino_mbd`` imports
(``scripts/test`` does, after python/tests)."""

from __future__ import annotations

import importlib.util
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _load(path: Path, name: str) -> types.ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_package = _load(ROOT / "python" / "tests" / "conftest.py", "pino_mbd_package_fixtures")
run = _package.run
quarter_car = _package.quarter_car


def script(file: str) -> types.ModuleType:
    """The research script `scripts/<file>` loaded as a module (its name has dashes)."""
    return _load(ROOT / "scripts" / file, file.removesuffix(".py").replace("-", "_"))
