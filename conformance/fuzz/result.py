"""What a campaign found and did: :class:`CampaignResult`, read by attribute; ``to_dict()`` is ``fuzz-summary.json``."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from .failure_files import Failure


@dataclass
class Observation:
    """A SHOULD the box broke (NON-STRICT), first seen on ``hex``."""

    clause: str
    requirement: str
    observed: str
    kind: str
    hex: str
    count: int = 1
    key: str = ""


@dataclass
class Sessions:
    """What the session state machine did, and the state transitions it reached (:mod:`.state_coverage`)."""

    runs: int = 0
    steps: int = 0
    coverage: dict[str, Any] = field(default_factory=dict)


@dataclass
class CampaignResult:
    """One campaign: what ran, what it reached, what it found."""

    tool: str
    command: str
    seed: int
    rerun: str
    target: str
    udp_target: str | None
    profile: dict[str, Any]
    extension: bool
    database: str
    started: str
    duration_s: float
    examples: int
    examples_per_s: float | None
    shrink_runs: int
    scheduled: int  # cases of the boundary schedule sent (:mod:`.schedule`)
    coverage: dict[str, Any]  # count, field, value and size space reached (:mod:`.input_coverage`)
    stateful: Sessions
    connections: int
    liveness_checks: int
    restarts: int  # times the box was brought back after it died
    by_kind: dict[str, int]
    disabled_kinds: list[str]
    stopped: str | None
    failures: list[Failure]
    non_strict: list[Observation]
    hint: str = ""  # how to get more out of the next campaign (e.g. a restart command)

    @property
    def failed(self) -> bool:
        return bool(self.failures)

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in vars(self).items() if k not in ("failures", "non_strict", "stateful")}
        out["stateful"] = asdict(self.stateful)
        out["failures"] = [f.to_dict() for f in self.failures]
        out["non_strict"] = [asdict(o) for o in self.non_strict]
        return out


__all__ = ["CampaignResult", "Observation", "Sessions"]
