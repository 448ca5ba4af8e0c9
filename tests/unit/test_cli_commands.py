"""conformance/commands/ registers every subcommand one way: each command module's ``COMMAND``
(a registry.Command) adds it, binds its handler and returns its parser; COMMANDS only lists them."""

from __future__ import annotations

import argparse

import pytest

from conformance.commands import COMMANDS, build_parser, main

NAMES = ("decode", "serve", "robot", "certify-robot", "run", "fuzz", "replay", "clauses", "wireshark", "diff", "analyze", "monitor",
         "soak")


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


def test_a_command_line_builds_only_its_own_command() -> None:
    parser = build_parser(only="decode")
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert tuple(sub.choices) == NAMES  # every name is still known (an unknown one is still named)
    assert sub.choices["decode"].get_default("func") is not None
    assert sub.choices["run"].get_default("func") is None  # named, not built: its module was not needed


def test_the_chosen_command_is_the_first_word_that_is_not_an_option() -> None:
    from conformance.commands import _chosen

    assert _chosen(["--lang", "zh-CN", "run", "--target", "x"]) is None  # the top level has no --lang: a usage error
    assert _chosen(["run", "--lang", "zh-CN"]) == "run"
    assert _chosen(["clauses"]) == "clauses"
    assert _chosen(["nosuch"]) is None and _chosen(["--version"]) is None and _chosen([]) is None


def test_every_command_module_is_named_for_its_command() -> None:
    assert tuple(command.name for command in COMMANDS) == NAMES
