"""``fuzz`` options for gating CI on a campaign: a case budget, the first finding, and the box as a child.

* ``--budget-cases N``: the campaign sends N cases (frame cases and session steps
  together, the stateful share of them steps), however fast the machine is: with a
  fixed ``--seed`` a CI run sends the same cases every time. (``--max-examples N`` is
  the same budget under its older name.)
* ``--until-first``: stop at the first *confirmed* finding (rerun on a fresh
  connection, or a death that killed the box again after a restart) and exit 1.
* ``--restart-cmd CMD``: the box is the fuzz command's child (:mod:`.box_process`):
  when the target does not answer at the start, CMD starts it; after a death CMD
  restarts it; what each incarnation writes is kept, and the one that died has its
  last words attached to the finding. The box is stopped at the end.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from ..harness.target import Target, check_reachable
from ..i18n import _
from .box_process import BoxProcess

#: How long a box started by ``--restart-cmd`` may take to accept connections.
START_WAIT_S = 30.0


def add_gating_arguments(p: argparse.ArgumentParser, budget: Any) -> None:
    """``--budget-cases`` (in the ``budget`` group, exclusive with ``--duration``) and ``--until-first``."""
    budget.add_argument("--budget-cases", type=int, metavar="N", dest="max_examples",
                        help=_("the campaign's budget in cases (frame cases and session steps), independent of the "
                               "machine's speed: with --seed, reproducible CI runs (same as --max-examples)"))
    p.add_argument("--until-first", action="store_true",
                   help=_("stop at the first confirmed finding and exit 1 (CI gating)"))


@contextmanager
def box_child(cmd: str | None, target: Target | None, time_out_s: float,
              log: Callable[[str], None] = print) -> Iterator[BoxProcess | None]:
    """The box as the command's child when ``cmd`` is given: started by it if ``target`` does not answer yet;
    stopped at the end. Raises ValueError when it does not come up."""
    if not cmd or target is None:  # no command, or the bundled box (it restarts itself)
        yield None
        return
    box = BoxProcess(cmd, log)
    try:
        if check_reachable(target, time_out_s) is not None:
            log(f"fuzz: {target} does not answer; starting the box: {cmd}")
            try:
                box.start()
            except RuntimeError as exc:
                raise ValueError(f"--restart-cmd could not start the box: {exc}") from None
            if not wait_reachable(target, time_out_s, START_WAIT_S):
                words = box.last_words(0.0)
                why = f" ({words.summary()})" if words is not None else ""
                raise ValueError(f"--restart-cmd started, but {target} did not answer within {START_WAIT_S:g} s{why}")
        yield box
    finally:
        box.close()


def wait_reachable(target: Target, time_out_s: float, wait_s: float) -> bool:
    deadline = time.monotonic() + wait_s
    while check_reachable(target, min(time_out_s, 1.0)) is not None:
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True


__all__ = ["START_WAIT_S", "add_gating_arguments", "box_child", "wait_reachable"]
