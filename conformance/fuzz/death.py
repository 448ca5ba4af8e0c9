"""R2: the box died during a campaign. Which input killed it?

Not shrunk by hypothesis: once a liveness check finds that the box no longer answers a
fresh connection, the campaign stops. The suspects are the cases run since the last good
liveness check (:class:`Seen`). After a restart of the bundled box, or once the box is
back by itself, each suspect is rerun on a fresh connection followed by a liveness check
(the one whose answer was odd first); the case after which the box dies again is the
killer, and the box is brought back once more. If the box does not come back, the odd
case (if any) or all the suspects are written, unconfirmed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..harness.transcript import Transcript
from .config import CampaignConfig
from .evidence import Failure, clauses_of
from .executor import Executor, Result, alive
from .strategies import FuzzCase

STOPPED = "the box stopped answering new connections (R2)"


@dataclass
class Seen:
    """A case run since the last good liveness check, and what it got."""

    case: FuzzCase
    result: Result


def recover(config: CampaignConfig, executor: Executor) -> bool:
    """Restart the box (when the campaign can) and wait until it answers a fresh connection."""
    if config.restart is not None:
        try:
            config.restart()
        except Exception as exc:  # noqa: BLE001 - reported, the campaign stops anyway
            config.log(f"fuzz: could not restart the box: {exc}")
            return False
    wait = config.recover_s if config.recover_s is not None else executor.time_out_s
    deadline = time.monotonic() + wait
    while True:
        if alive(executor.check_alive()):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)


def find_killer(config: CampaignConfig, window: list[Seen], executor: Executor,
                number: int) -> tuple[Failure, Transcript | None]:
    """The death as failure ``number`` (not yet written), and the transcript of the reruns (None: none ran).

    ``executor`` is the campaign's: it is closed here, and used to check whether the box is back."""
    suspects = [s.case for s in window]
    prime = next((s.case for s in window if s.result.anomaly), None)
    config.log(f"fuzz: R2: the box no longer answers a fresh connection; {len(suspects)} cases since the last good "
               "liveness check are suspects")
    executor.close()
    killer: FuzzCase | None = None
    evidence: Transcript | None = None
    if recover(config, executor):
        tr = Transcript(case_id=f"FUZZ-{number:03d}")
        probe = Executor(config.target, config.profile, tr, udp_target=config.udp_target, extension=config.extension,
                         liveness_every=1)
        probe.isolate = True
        order = ([prime] if prime is not None else []) + [c for c in suspects if c is not prime]
        for case in order:
            result = probe.run(case, f"is this the case that kills the box? {case.describe()}")
            if result.liveness is not None and not alive(result.liveness):
                killer = case
                break
        probe.close()
        evidence = tr
        if killer is not None:
            recover(config, executor)
    confirmed = killer is not None
    if killer is None and prime is not None:
        killer = prime
    cases = [killer] if killer is not None else suspects
    if confirmed:
        how = "rerun on its own after the box came back, it killed the box again"
    elif killer is not None:
        how = "the box closed or stopped answering right after it (not confirmed: the box did not come back)"
    else:
        how = "one of these cases (the box did not come back to tell which)"
    message = f"R2: after this input the box no longer accepts and answers new connections; {how}"
    clauses = ["R2"] + [c for c in (clauses_of(cases[0]) if len(cases) == 1 else []) if c != "R2"]
    return Failure(number, "death", clauses, message, cases, confirmed=confirmed), evidence


__all__ = ["STOPPED", "Seen", "find_killer", "recover"]
