"""conformance/commands/ registers every subcommand one way: each command module's ``COMMAND``
(a registry.Command) adds it, binds its handler and returns its parser; COMMANDS only lists them."""

from __future__ import annotations

import argparse

import pytest

from conformance.commands import COMMANDS, build_parser, main

NAMES = ("decode", "serve", "robot", "certify-robot", "run", "fuzz", "replay", "clauses", "wireshark", "diff", "analyze", "monitor")


def test_every_add_parser_registers_one_command_with_its_handler() -> None:
    sub = argparse.ArgumentParser().add_subparsers(dest="command")
    for command in COMMANDS:
        before = set(sub.choices)
        parser = command.add_to(sub)
        (name,) = set(sub.choices) - before
        assert sub.choices[name] is parser, name
        assert callable(parser.get_default("func")), name
    assert tuple(sub.choices) == NAMES


def test_the_command_line_lists_the_same_commands() -> None:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert tuple(sub.choices) == NAMES


def test_an_unknown_option_is_a_usage_error(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["clauses", "--no-such-flag"])
    assert exc.value.code == 2 and "unrecognized arguments: --no-such-flag" in capsys.readouterr().err


def test_decode_still_names_the_clause(capsys) -> None:
    assert main(["decode", "fefe000201000000000000000000"]) == 1
    assert "F2" in capsys.readouterr().out
