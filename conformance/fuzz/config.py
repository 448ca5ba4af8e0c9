"""What a fuzz campaign is asked to do: the target, the budget, the evidence to keep and the limits.

:class:`CampaignConfig` is read by the campaign's loop (:mod:`.campaign`), by the triage of
a failure (:mod:`.triage`), by the search for the input that killed the box (:mod:`.death`)
and by the session state machine (:mod:`.session_runner`); none of them needs the campaign itself.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hypothesis.database import ExampleDatabase

from ..harness.target import Target
from ..harness.transcript import Transcript
from ..protocol import DEFAULT_PROFILE, Profile
from .box_process import BoxProcess


@dataclass
class CampaignConfig:
    target: Target
    profile: Profile = DEFAULT_PROFILE
    udp_target: Target | None = None
    stream_target: Target | None = None
    seed: int | None = None
    max_examples: int | None = None  # fuzz cases (frames); stateful steps come on top of the share
    duration_s: float | None = None
    report_dir: Path | None = Path("reports/fuzz")  # None: no files (the suite's case keeps its own evidence)
    pcap_dir: Path | None = None
    capture: str = "failures"  # failures | all | off
    database: ExampleDatabase | None = None
    database_label: str = "off"
    extension: bool = True
    batch: int = 32
    liveness_every: int = 64
    max_failures: int = 5
    categories: tuple[str, ...] = ()
    stateful_share: float = 0.2  # of the budget for the session state machine (0: off)
    restart: Callable[[], None] | None = None  # brings a dead box back (the bundled box)
    box: BoxProcess | None = None  # the box as this campaign's child (fuzz --restart-cmd): its last words are kept
    until_first: bool = False  # stop at the first confirmed finding (fuzz --until-first)
    recover_s: float | None = None  # how long to wait for a dead box to come back (default: time_out)
    chunk_examples: int = 100
    mutants: int = 4  # cheap mutants of the recent hypothesis cases after each one (:mod:`.mutants`; 0: none)
    settle_s: float = 0.05
    progress_s: float = 2.0
    log: Callable[[str], None] = print
    command: str = ""
    transcript: Transcript | None = None  # record into this transcript (a case's) instead of the campaign's own
    name: str = "fuzz-failure"  # file names: <name>-001.json, <name>-001.pcapng
    bundled: bool = False  # the target is the bundled box this command started (the rerun hint omits --target)

    def __post_init__(self) -> None:
        if self.capture not in ("failures", "all", "off"):
            raise ValueError("capture must be failures, all or off")
        if not 0 <= self.stateful_share <= 1:
            raise ValueError("the stateful share must be between 0 and 1")
        if self.max_examples is not None and self.max_examples < 1:
            raise ValueError("--max-examples must be at least 1")
        if self.duration_s is not None and self.duration_s <= 0:
            raise ValueError("--duration must be positive")
        if self.batch < 1 or self.liveness_every < 1 or self.chunk_examples < 1:
            raise ValueError("batch, liveness interval and chunk size must be at least 1")


def new_seed() -> int:
    return random.SystemRandom().randrange(1, 2**32)


__all__ = ["CampaignConfig", "new_seed"]
