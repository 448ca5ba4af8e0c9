"""A block count refused at the pose's block size only (diagnose/titles.size_undecided): a frame-size limit and a
count limit both fit, so the title says both, with the figures, and never claims one."""

from __future__ import annotations

from conformance.diagnose import titles


def test_both_stories_and_the_figures_are_named() -> None:
    title = titles.size_undecided(164, 4089, 4114, "5-byte blocks are accepted up to 255 (1289 bytes)")
    assert "164 or more blocks" in title and "4114 bytes" in title and "163 blocks, 4089 bytes" in title
    assert "size in bytes" in title and "count of 25-byte blocks" in title and "B5" in title
    assert "4096-byte receive buffer?" in title  # a power of two inside the window, said as a question


def test_no_buffer_guess_without_a_power_of_two_in_the_window() -> None:
    title = titles.size_undecided(120, 2989, 3014, "nothing else")
    assert "receive buffer" not in title and "120 or more blocks" in title
