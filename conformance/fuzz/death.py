"""R2: the box died during a campaign. Which input killed it?

The suspects are the cases run since the last good liveness check (:class:`Seen`). The
box is brought back (the bundled box restarts itself; ``--restart-cmd CMD`` runs a
command; else the campaign waits time_out for a supervisor to restart it) and:

1. each suspect is rerun on a fresh connection followed by a liveness check (the one
   whose answer was odd first); the case after which the box dies again is the killer;
2. if no single case kills it, the whole history since the last liveness check is
   replayed as it was sent (the same cases, a new connection where the campaign opened
   one); if that kills the box, it is shrunk (:func:`.restart.shrink`, ddmin) to the
   shortest sequence that still does, bringing the box back after every kill.

The death is then confirmed, and the box is brought back once more, so the campaign
goes on to find the next defect (:attr:`Verdict.back`). If the box does not come back
the odd case (if any) or all the suspects are written, unconfirmed, with a hint on
how to give a restart command.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..harness.transcript import Transcript
from ..i18n import N_
from ..protocol import peek_header
from .config import CampaignConfig
from .executor import Executor, Result, alive
from .failure_files import Failure, clauses_of
from .last_words import telling
from .restart import History, Step, kills, recover, shrink
from .strategies import FuzzCase

STOPPED = "the box stopped answering new connections (R2)"
RESTART_HINT = N_("give the campaign a way to restart the box (fuzz --restart-cmd 'CMD', e.g. 'systemctl restart "
                  "aibox' or 'docker restart aibox') and it confirms the death, shrinks it and goes on")  # translated where printed


@dataclass
class Seen:
    """A case run since the last good liveness check, and what it got."""

    case: FuzzCase
    result: Result


@dataclass
class Death:
    """What :func:`find_killer` found: the failure (not yet written), the evidence, and whether the box is back."""

    failure: Failure
    evidence: Transcript | None
    back: bool


def history_of(window: list[Seen]) -> History:
    """The window as it was sent: a new connection where the connection id changed or the case was first on it."""
    out: History = []
    last = None
    for s in window:
        out.append(Step(s.case, s.result.fresh or s.result.conn != last or s.case.eof))
        last = s.result.conn
    return out


def _single(config: CampaignConfig, window: list[Seen], tr: Transcript) -> FuzzCase | None:
    """The one suspect that kills the box on its own (the odd one tried first), else None."""
    prime = next((s.case for s in window if s.result.anomaly), None)
    order = ([prime] if prime is not None else []) + [s.case for s in window if s.case is not prime]
    probe = Executor(config.target, config.profile, tr, udp_target=config.udp_target, extension=config.extension,
                     liveness_every=1)
    probe.isolate = True
    try:
        for case in order:
            result = probe.run(case, f"is this the case that kills the box? {case.describe()}")
            if result.liveness is not None and not alive(result.liveness):
                return case
    finally:
        probe.close()
    return None


def find_killer(config: CampaignConfig, window: list[Seen], executor: Executor, number: int) -> Death:
    """The death as failure ``number``; ``executor`` is the campaign's (closed here, used to see the box is back).

    With the box as the campaign's child (``--restart-cmd``) the finding carries what the incarnation that
    died wrote last (or, when it wrote nothing telling, what the one that died again to confirm it wrote)."""
    box = config.box
    if box is None:
        return _find_killer(config, window, executor, number)
    first = len(box.incarnations)
    words = [box.last_words()]
    death = _find_killer(config, window, executor, number)
    words += [inc.last_words(0.0) for inc in box.incarnations[first:-1]]
    death.failure.last_words = telling(words)
    if death.failure.last_words is not None:
        config.log(f"fuzz: R2: {death.failure.last_words.summary()}")
    return death


def _find_killer(config: CampaignConfig, window: list[Seen], executor: Executor, number: int) -> Death:
    suspects = [s.case for s in window]
    prime = next((s.case for s in window if s.result.anomaly), None)
    config.log(f"fuzz: R2: the box no longer answers a fresh connection; {len(suspects)} cases since the last good "
               "liveness check are suspects")
    executor.close()
    if not recover(config, executor):
        return _unconfirmed(config, number, suspects, prime)
    tr = Transcript(case_id=f"FUZZ-{number:03d}")
    killer = _single(config, window, tr)
    if killer is not None:
        back = recover(config, executor)
        how = "rerun on its own after the box came back, it killed the box again"
        clauses = ["R2"] + [c for c in clauses_of(killer) if c != "R2"]
        return Death(Failure(number, "death", clauses, _message(how), [killer], confirmed=True, keys=["R2/death"]),
                     tr, back)
    history = history_of(window)
    if history and kills(config, history, tr):
        shrunk, runs = shrink(config, history, tr, lambda: recover(config, executor))
        back = recover(config, executor) if kills(config, shrunk, tr) else alive(executor.check_alive())
        how = (f"no case kills it on its own; the {len(history)} cases since the last liveness check, replayed "
               f"after the box came back, killed it again, and so do these {len(shrunk)} of them, in this order "
               f"({runs} replays to shrink it; replay the vector file to see it)")
        failure = Failure(number, "death", ["R2"], _message(how), [s.case for s in shrunk], confirmed=True,
                          shrunk=len(shrunk) < len(history), keys=["R2/death"])
        failure.new_connections = [s.new_connection for s in shrunk]
        return Death(failure, tr, back)
    how = ("neither one of the cases since the last liveness check nor all of them replayed killed it again "
           "after it came back (not confirmed)")
    cases = [prime] if prime is not None else suspects
    return Death(Failure(number, "death", ["R2"], _message(how), cases, confirmed=False, keys=["R2/death"]), tr,
                 alive(executor.check_alive()))


def death_key(failure: Failure) -> str:
    """Tells deaths apart: the killer's action and block count when it is one well-formed request, else its
    first clause or strategy; "sequence" for a history that kills only as a whole."""
    if len(failure.cases) != 1:
        return "R2/death/sequence"
    case = failure.cases[0]
    head = peek_header(case.data)
    if case.valid and len(case.expects) == 1 and head is not None:
        return f"R2/death/{head.action:02X}x{head.block_count}"
    return f"R2/death/{case.first_clause or case.kind}"


def _message(how: str) -> str:
    return f"R2: after this input the box no longer accepts and answers new connections; {how}"


def _unconfirmed(config: CampaignConfig, number: int, suspects: list[FuzzCase], prime: FuzzCase | None) -> Death:
    hint = "" if config.restart is not None else f"; {RESTART_HINT}"
    if prime is not None:
        how = f"the box closed or stopped answering right after it (not confirmed: the box did not come back{hint})"
    else:
        how = f"one of these cases (the box did not come back to tell which{hint})"
    cases = [prime] if prime is not None else suspects
    clauses = ["R2"] + [c for c in (clauses_of(cases[0]) if len(cases) == 1 else []) if c != "R2"]
    return Death(Failure(number, "death", clauses, _message(how), cases, confirmed=False, keys=["R2/death"]), None,
                 False)


__all__ = ["RESTART_HINT", "STOPPED", "Death", "Seen", "death_key", "find_killer", "history_of", "recover"]
