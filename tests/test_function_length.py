"""No function over 80 lines in the library (issue 46), numerical kernels aside.

A numba-compiled function (decorated with ``njit``, ``jit`` or any ``numba.*``) is a hot loop
kept whole on purpose; every other function is split into named helpers before it grows past
the limit.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 80


def _compiled(function: ast.FunctionDef) -> bool:
    return any("jit" in ast.unparse(d) or ast.unparse(d).startswith("numba")
               for d in function.decorator_list)


def _long_functions(package: str) -> list[str]:
    long = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                    and node.end_lineno - node.lineno + 1 > LIMIT and not _compiled(node)):
                long.append(f"{path.relative_to(ROOT)}::{node.name} "
                            f"({node.end_lineno - node.lineno + 1} lines)")
    return long


@pytest.mark.parametrize("package", ["benchmarks", "integrators", "problems"])
def test_no_function_over_80_lines_outside_kernels(package):
    assert _long_functions(package) == []
