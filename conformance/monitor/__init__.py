"""``isight-conformance monitor``: an in-line proxy that judges a live robot ↔ box line.

:mod:`.proxy` (TCP) and :mod:`.udp_proxy` forward the bytes; :mod:`.hub` hands them to
:mod:`.line_recording`, which draws them as packets into the pcapng :mod:`.ring` and into
``analyze``'s engine; :mod:`.live_findings` watches the findings (printed by :mod:`.view`,
grouped into root causes, excused when an injected fault caused them); :mod:`.faults`
and :mod:`.split` inject protocol-aware faults, :mod:`.reactions` records what the robot
did next; :mod:`.monitor_reports` writes the reports and :mod:`.monitor_loop` runs it all.
:mod:`.alarms` raises live alarms (a box silent past time_out, a slow stream, a refused
connection); :mod:`.tally` keeps totals and latency histograms; :mod:`.exposition` serves
them to Prometheus (``--metrics``) and :mod:`.livestate`, :mod:`.livepage` and
:mod:`.liveserve` the live page (``--http``), both over :mod:`.webserve`.
"""
