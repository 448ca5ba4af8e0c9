"""``isight-conformance monitor``: an in-line proxy that judges a live robot ↔ box line.

:mod:`.proxy` (TCP) and :mod:`.udp` forward the bytes; :mod:`.hub` hands them to
:mod:`.wire`, which draws them as packets into the pcapng :mod:`.ring` and into
``analyze``'s engine; :mod:`.judge` watches the findings (printed by :mod:`.view`,
grouped into root causes, excused when an injected fault caused them); :mod:`.faults`
and :mod:`.split` inject protocol-aware faults, :mod:`.reactions` records what the robot
did next; :mod:`.report` writes the reports and :mod:`.runner` runs it all.
"""
