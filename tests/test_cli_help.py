"""Every command's --help states every option's default (or that it is required, a flag, or what
happens without it) and the unit of every physical quantity."""

import argparse

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
