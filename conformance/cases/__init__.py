"""The conformance case catalogue: one module per clause family (``frame.py``, ``blocks.py``, ...).

The pytest plugin collects these modules (:func:`conformance.pytest_plugin.pytest_collect_file`);
their helpers live in :mod:`conformance.suite`, the one import a case author needs.

Run with ``isight-conformance run`` or ``pytest --pyargs conformance.cases --target HOST:PORT``.
Every case is marked with :func:`conformance.suite.record.case` (stable ID, clauses,
level, expectation) and takes the ``isight`` fixture (:class:`~conformance.suite.case_context.CaseContext`).
"""
