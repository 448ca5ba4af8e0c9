"""The conformance case catalogue, as pytest modules.

Run with ``isight-conformance run`` or ``pytest --pyargs conformance.cases --target HOST:PORT``.
Every case is marked with :func:`conformance.suite.record.case` (stable ID, clauses,
level, expectation) and takes the ``isight`` fixture (:class:`~conformance.suite.case_context.CaseContext`).
"""
