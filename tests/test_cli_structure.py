"""The command line is thin: each command's ``--help`` is its output (the standard output, exit
status 0), and no function of ``benchmarks/cli`` is longer than a screen — a command parses,
checks, calls the library and prints; the long work is the library's."""

import argparse
import ast
from pathlib import Path

import pytest

from benchmarks.cli.main import build_parser, main

#: the longest function of benchmarks/cli, in lines (def to last line)
MOST_LINES = 60
CLI = Path(__file__).resolve().parents[1] / "benchmarks" / "cli"


def _commands() -> list[list[str]]:
    """Every command and sub-command (``lab fit``) as its words."""
    def walk(parser, prefix):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, command in action.choices.items():
                    yield [*prefix, name]
                    yield from walk(command, [*prefix, name])
    return list(walk(build_parser(), []))


@pytest.mark.parametrize("words", _commands(), ids=" ".join)
def test_help_is_the_commands_output(words, capsys):
    with pytest.raises(SystemExit) as stop:
        main([*words, "--help"])
    assert stop.value.code == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"usage: rsfbench {' '.join(words)}") and "--help" in out
    assert err == ""


def test_no_function_of_the_command_line_is_over_a_screen():
    long = []
    for path in sorted(CLI.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MOST_LINES:
                    long.append(f"{path.name}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, long
