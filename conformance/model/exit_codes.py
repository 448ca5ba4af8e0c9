"""Every exit status the ``isight-conformance`` commands return, defined once.

The suite's commands (``run``, ``fuzz``, ``replay``, ``analyze``, ``certify-robot``, ``monitor``,
``diff``, ``decode``, ``clauses``, ``wireshark``, ``serve``, fleet runs) share one meaning:

* ``EXIT_OK`` (0): nothing FAILed or ERRORed (``diff``: nothing got worse);
* ``EXIT_FAILED`` (1): a FAIL or ERROR, a fuzz failure, a vector that still fails (``diff``: something got worse);
* ``EXIT_USAGE`` (2): a usage error, an unreachable target, a bad file, cannot listen;
* ``EXIT_INCOMPLETE`` (3): the run was cut short (Ctrl-C, SIGTERM, SIGHUP); the reports say INCOMPLETE;
* ``EXIT_INTERRUPTED`` (130): Ctrl-C outside a run's own handling (the shell's 128 + SIGINT).

The ``robot`` command (the simulated robot) tells how its session ended: ``EXIT_OK``,
``EXIT_MISBEHAVED`` (1, the box broke the protocol), ``EXIT_USAGE`` (2), ``EXIT_NOT_READY`` (3,
CycleOn 0001 / ProgIdx 409), ``EXIT_TIMEOUT`` (4, no answer within time_out), ``EXIT_CONNECTION``
(5, refused or closed by the box).
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INCOMPLETE = 3
EXIT_INTERRUPTED = 130

#: ``diff``: nothing got worse / something did
EXIT_SAME, EXIT_WORSE = EXIT_OK, EXIT_FAILED

#: ``robot``: how the simulated robot's session ended
EXIT_MISBEHAVED = 1  # the box broke the protocol (wrong code, action, malformed answer, ...)
EXIT_NOT_READY = 3  # CycleOn answered 0001 / ProgIdx answered 409: the cycle is inconclusive (S2)
EXIT_TIMEOUT = 4  # no answer within time_out / vision_time_out (T1, E3)
EXIT_CONNECTION = 5  # connection refused, failed or closed by the box
