"""The diagnose phase: each candidate root cause's competing explanations, told apart by live experiments.

After the catalogue, :func:`.phase.diagnose` takes the root causes read from the verdicts
(:mod:`conformance.engine.rootcause`) and, within a bounded time (:data:`.phase.BUDGET_S`),
sends the few requests that tell their stories apart, each on a fresh connection:

* :mod:`.hypotheses`: the typed values (what was heard, an experiment, a hypothesis and its
  status, a mechanism the experiments confirmed, a root cause's diagnosis) and the pure
  judgements that turn what the box did into hypotheses confirmed or ruled out;
* :mod:`.experiments`: the live exchanges (fresh connection, every wait bounded);
* :mod:`.bisect`: a threshold pinned by bisection; :mod:`.shrink`: the fewest frames;
* :mod:`.families`: the experiment families (answers per action, size: count vs bytes vs
  index, state after an error, cycle, connection);
* :mod:`.conn_peers`, :mod:`.conn_state`: a close the requests alone do not show, told apart by
  what triggers it (another connection opening or running a cycle, idle time, connection age);
  :mod:`.conn_deaths`: a box that stops accepting connections, the input before it vs a count of
  connections never freed (the session's evidence); their titles in :mod:`.conn_titles`;
* :mod:`.titles`: the one-line titles a firmware engineer reads once;
* :mod:`.repro`: ``rootcause-N.json`` (isight-vectors-1) and its judgement on ``replay``.
"""
