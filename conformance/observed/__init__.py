"""The model of observed traffic that ``certify-robot`` and ``analyze`` both judge from.

``certify-robot`` observes a robot live (its listener records every connection);
``analyze`` observes a capture (it rebuilds the connections from packets). Both then
read the same things, sans-I/O:

* :mod:`.connections`: sessions, connections and exchanges (who, when, how they ended);
* :mod:`.robot_frames`: what the robot sent, decoded frame by frame (:class:`FrameRecord`),
  and the F4 byte-order heuristic;
* :mod:`.session`: the session view (command and stream connections, the cut, the
  canonical order S1/E4, awaited answers A1/T1);
* :mod:`.stream_timing`: the pose stream's rate and jitter (T2);
* :mod:`.robot_catalogue`: the robot-role cases (``RB-*``) whose requirements both report.

Nothing here imports ``certify`` or ``analyze`` (tests/unit/test_import_graph.py).
"""
