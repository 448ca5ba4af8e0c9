"""Endurance: ``isight-conformance soak``, hours of production against a box, judged as a trend.

Modules: :mod:`.duration` (``--duration``), :mod:`.settings` (what a soak is asked, the event
plan), :mod:`.sessions` (the robot sessions and their planted events), :mod:`.player` (the loop),
:mod:`.sketch` and :mod:`.windows` (streaming statistics per window), :mod:`.trend` (Theil–Sen and
Mann–Kendall), :mod:`.judge` and :mod:`.verdicts` (the verdicts), :mod:`.resources` (psutil),
:mod:`.document`, :mod:`.evidence`, :mod:`.plots` and :mod:`.page` (soak.json, summary.json,
junit.xml, report.html), :mod:`.progress` (the live line), :mod:`.boxstart` and :mod:`.flow`.
"""
