"""Every command's --help states every option's default (or that it is required, a flag, or what
happens without it) and the unit of every physical quantity."""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.cli.main import build_parser
from benchmarks.cli.args import HelpFormatter

#: options that carry a physical quantity, and the unit their help must name
UNITS = {"--t-end": " s", "--wall-budget": " s", "--lc": "metres", "--curve-dt": " s", "--obs-recurrence": " s",
         "--sigma-recurrence": " s", "--connect-timeout": " s", "--worker-timeout": " s"}


def _commands():
    """Every command and sub-command (``lab fit``), by its name."""
    def walk(parser, prefix):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, command in action.choices.items():
                    yield f"{prefix}{name}", command
                    yield from walk(command, f"{prefix}{name} ")
    return sorted(walk(build_parser(), ""))


@pytest.mark.parametrize("name, command", _commands(), ids=[n for n, _ in _commands()])
def test_help_states_defaults_and_units(name, command):
    formatter = HelpFormatter(prog=command.prog)
    for action in command._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        flag = action.option_strings[0] if action.option_strings else action.dest
        text = formatter._get_help_string(action) or ""
        assert text, f"{name} {flag} has no help"
        said = ("default" in text or action.required or action.nargs == 0
                or isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)))
        assert said, f"{name} {flag}: no default stated: {text!r}"
        if flag in UNITS:
            assert UNITS[flag] in text, f"{name} {flag}: no unit ({UNITS[flag].strip()}): {text!r}"
    command.format_help()          # renders (a % in a help string would raise here)


def test_help_imports_neither_the_studies_nor_the_heavy_libraries():
    """`rsfbench --help` and every command's --help build the whole parser; what only a run
    needs waits for it (docs/api.md, "Start-up"): matplotlib (0.4 s of a 1.3 s start), the
    studies and the pipeline, the process pool's multiprocessing, scipy.optimize, the optional
    extras."""
    code = ("import sys, json\nfrom benchmarks.cli.main import build_parser\nbuild_parser()\n"
            "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=Path(__file__).resolve().parents[1])
    loaded = set(json.loads(done.stdout.splitlines()[-1]))
    waiting = ("matplotlib", "benchmarks.studies", "benchmarks.pipeline", "multiprocessing",
               "scipy.optimize", "emcee", "corner", "distributed", "numbalsoda")
    assert sorted(m for m in loaded if m.split(".")[0] in waiting or m in waiting
                  or any(m.startswith(w + ".") for w in waiting)) == []
