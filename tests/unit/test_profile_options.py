"""Profile options: --help shows each default as the value a user would type."""

from __future__ import annotations

import argparse

from conformance.runtime.profile_options import PROFILE_OPTIONS, add_profile_options, profile_from_options


def _help_texts() -> dict[str, str]:
    parser = argparse.ArgumentParser()
    add_profile_options(parser.add_argument)
    return {a.option_strings[0]: a.help or "" for a in parser._actions if a.option_strings[:1] != ["-h"]}


def test_checking_help_shows_a_value_the_flag_accepts():
    help_text = _help_texts()["--checking"]
    assert help_text.endswith("(default: strict)")
    assert "True" not in help_text and "False" not in help_text


def test_every_default_shown_is_accepted_by_its_flag():
    for opt in PROFILE_OPTIONS:
        shown = _help_texts()[opt.flag].rsplit("(default: ", 1)[1].rstrip(")")
        parser = argparse.ArgumentParser()
        add_profile_options(parser.add_argument)
        args = parser.parse_args([opt.flag, shown])  # the shown default typed back in parses ...
        assert profile_from_options(args) == profile_from_options({})  # ... and changes nothing
