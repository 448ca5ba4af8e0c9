"""Fleet files (conformance/fleet/spec.py): what a valid one gives, and every error naming its line."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from conformance.commands.run import add_arguments as add_run_arguments
from conformance.fleet.spec import FleetFileError, command_line_overrides, load_fleet, parse_fleet

GOOD = """\
# line 1: a fleet of three
[defaults]
time_out = 500
cases = ["A*", "F*"]

[[box]]
name = "line1-cell1"
target = "10.0.1.11:9004"
udp_target = "10.0.1.11:9004"
first_index = 1
expected_failures = ["T2-01", "R5-02", "T2-01"]

[[box]]
name = "line1-cell2"
target = "10.0.1.12"
"crc-byte-order" = "little"
checking = false
time_out_ms = 800
sequence = ["seq/startup.json"]

[[box]]
name = "bench"
"""


def test_a_valid_file_gives_each_box_its_settings(tmp_path: Path) -> None:
    (tmp_path / "seq").mkdir()
    (tmp_path / "seq" / "startup.json").write_text("{}")
    path = tmp_path / "fleet.toml"
    path.write_text(GOOD)
    spec = load_fleet(path)
    a, b, c = spec.boxes
    assert [x.name for x in spec.boxes] == ["line1-cell1", "line1-cell2", "bench"]
    assert [x.line for x in spec.boxes] == [6, 13, 21]
    assert a.expected_failures == ("T2-01", "R5-02")  # duplicates folded, order kept
    assert a.flags() == ["--time-out=500", "--cases=A*", "--cases=F*", "--target=10.0.1.11:9004",
                         "--udp-target=10.0.1.11:9004", "--first-index=1"]
    # keys with - or _, profile field names as aliases; a box's own value beats [defaults]
    assert b.settings["crc-byte-order"] == ("little",)
    assert b.settings["checking"] == ("false",)
    assert b.settings["time-out"] == ("800",)
    assert b.settings["sequence"] == (str(tmp_path / "seq" / "startup.json"),)  # relative to the fleet file
    assert b.target == "10.0.1.12" and b.expected_failures is None
    assert c.target is None and c.flags() == ["--time-out=500", "--cases=A*", "--cases=F*"]  # the bundled box


def test_command_line_settings_apply_to_every_box_over_the_file(tmp_path: Path) -> None:
    (tmp_path / "seq").mkdir()
    (tmp_path / "seq" / "startup.json").write_text("{}")
    parser = argparse.ArgumentParser()
    add_run_arguments(parser)
    args = parser.parse_args(["--targets", "f.toml", "--cases", "A4-*", "--checking", "lenient", "--jobs", "2"])
    overrides = command_line_overrides(args)
    assert overrides == {"cases": ("A4-*",), "checking": ("false",)}
    spec = parse_fleet(GOOD.replace("seq/", str(tmp_path / "seq") + "/"), tmp_path / "f.toml", overrides)
    assert all(box.settings["cases"] == ("A4-*",) for box in spec.boxes)
    assert all(box.settings["checking"] == ("false",) for box in spec.boxes)
    assert spec.boxes[0].settings["time-out"] == ("500",)


def error(text: str) -> FleetFileError:
    with pytest.raises(FleetFileError) as exc:
        parse_fleet(text, "plant.toml")
    return exc.value


@pytest.mark.parametrize(("text", "line", "words"), [
    # a malformed file: the TOML parser's line
    ('[[box]]\nname = "a"\n\n[[box]]\nname = "b"\ntarget = \n', 6, "not valid TOML"),
    ('[[box]]\nname = "a"\nname = "b"\n', 3, "not valid TOML"),
    # a duplicate name: the second one's line, naming the first
    ('[[box]]\nname = "a"\n\n[[box]]\nname = "b"\n\n[[box]]\n  name = "A"\n', 8, "duplicate box name 'A' (first at line 2)"),
    # a bad target
    ('[[box]]\nname = "a"\n\n[[box]]\nname = "b"\ntarget = "10.0.0.5:http"\n', 6, "target = '10.0.0.5:http'"),
    ('[[box]]\nname = "a"\nudp_target = "10.0.0.5:70000"\n', 3, "udp_target"),
    ('[[box]]\nname = "a"\ntarget = 9004\n', 3, "target = 9004: write it as a string"),
    # an unknown setting
    ('[[box]]\nname = "a"\n\n  first_indx = 1\n', 4, "unknown setting 'first_indx'"),
    ('[defaults]\nspeed = 3\n[[box]]\nname = "a"\n', 2, "unknown setting 'speed'"),
    # bad values, each on its key's line
    ('[[box]]\nname = "a"\nfirst_index = 2\n', 3, "first_index = 2: invalid choice"),
    ('[[box]]\nname = "a"\ntime_out = "soon"\n', 3, "expected a whole number, not 'soon'"),
    ('[[box]]\nname = "a"\ntime_out = -1\n', 3, "time-outs must be positive"),
    ('[[box]]\nname = "a"\nchecking = "medium"\n', 3, "expected strict or lenient"),
    ('[[box]]\nname = "a"\ntarget = ["a:1", "b:2"]\n', 3, "takes one value, not a list"),
    ('[[box]]\nname = "a"\ncases = [{ x = 1 }]\n', 3, "is not a value"),
    ('[[box]]\nname = "a"\nsequence = "missing.json"\n', 3, "no such file"),
    ('[[box]]\nname = "a"\nudp_target = "x:1"\n"udp-target" = "y:2"\n', 4, "set twice"),
    # what the fleet sets itself
    ('[[box]]\nname = "a"\nreport_dir = "r"\n', 3, "set by the fleet"),
    # names and expected failures
    ('[[box]]\ntarget = "10.0.0.5"\n', 1, "has no name"),
    ('[[box]]\nname = "../up"\n', 2, "a name is 1-64 letters"),
    ('[[box]]\nname = 7\n', 2, "a name is"),
    ('[[box]]\nname = "a"\nexpected_failures = "T2-01"\n', 3, "give a list of case IDs"),
    ('[defaults]\nexpected_failures = ["T2-01"]\n[[box]]\nname = "a"\n', 2, "belongs in each [[box]] table"),
    # the file's shape
    ('[box]\nname = "a"\n', 1, "[[box]] table"),
    ('title = "plant"\n[[box]]\nname = "a"\n', 1, "unknown top-level key 'title'"),
    ('[[box]]\nname = "a"\n[plant]\nx = 1\n', 3, "unknown top-level key 'plant'"),
])
def test_every_error_names_its_line(text: str, line: int, words: str) -> None:
    exc = error(text)
    assert exc.line == line, str(exc)
    assert words in str(exc)
    assert str(exc).startswith(f"plant.toml:{line}: ")
    assert "\n" not in str(exc)


def test_a_file_without_boxes_is_an_error() -> None:
    assert "no [[box]] table" in str(error('[defaults]\ntime_out = 500\n'))
    assert "no [[box]] table" in str(error(""))


def test_unreadable_files(tmp_path: Path) -> None:
    (tmp_path / "latin1.toml").write_bytes(b'[[box]]\nname = "caf\xe9"\n')
    with pytest.raises(FleetFileError, match="not UTF-8"):
        load_fleet(tmp_path / "latin1.toml")
    with pytest.raises(OSError):
        load_fleet(tmp_path / "missing.toml")
