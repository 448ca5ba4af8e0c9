"""The run engine beside :mod:`conformance.pytest_plugin`: each case's result (:mod:`.results`, :mod:`.wirelog`),
the session's collected results and facts (:mod:`.collected`), the lanes of a run (:mod:`.lanes`), the root causes
(:mod:`.rootcause`, :mod:`.patterns`) and the signal handling (:mod:`.signals`). Above :mod:`conformance.suite`:
it runs the cases; no case imports it."""
