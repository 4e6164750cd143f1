"""docs/api.md states the public API once: each package's section names exactly its
``__all__``, and every name there exists."""

import importlib
import re
from pathlib import Path

import pytest

API = Path(__file__).resolve().parents[1] / "docs" / "api.md"
PACKAGES = ["problems", "integrators", "benchmarks.records", "benchmarks.physics",
            "benchmarks.devtools", "benchmarks.ensemble", "benchmarks.inversion",
            "benchmarks.pipeline", "benchmarks.cli"]


def _sections() -> dict[str, set[str]]:
    sections, current = {}, None
    for line in API.read_text(encoding="utf-8").splitlines():
        if m := re.match(r"## `([\w.]+)`", line):
            current = sections.setdefault(m.group(1), set())
        elif current is not None and (m := re.match(r"\| `(\w+)` \|", line)):
            current.add(m.group(1))
    return sections


def test_every_curated_package_has_a_section():
    assert set(_sections()) == set(PACKAGES)


@pytest.mark.parametrize("package", PACKAGES)
def test_a_section_names_exactly_the_packages_public_api(package):
    module = importlib.import_module(package)
    assert _sections()[package] == set(module.__all__)
    for name in module.__all__:
        assert getattr(module, name) is not None
