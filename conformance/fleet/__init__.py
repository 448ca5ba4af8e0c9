"""Fleet runs: ``isight-conformance run --targets FILE [--jobs N]``, one ``run`` process per box.

* :mod:`.spec`: the fleet file (TOML, a ``[[box]]`` table per box), checked with line numbers;
* :mod:`.children`: the child processes, ``jobs`` at a time, stopped together on a signal;
* :mod:`.fleet_results`, :mod:`.fleet_page`: fleet.json and fleet.html;
* :mod:`.fleet_run`: the run itself (:func:`run_fleet`); its handler is :mod:`conformance.commands.fleet`.
"""

from __future__ import annotations

from .fleet_run import run_fleet

__all__ = ["run_fleet"]
