"""A fuzz campaign's configuration (conformance/fuzz/config.py): bad settings are refused with a clear message."""

from __future__ import annotations

from typing import Any

import pytest

from conformance.fuzz.config import CampaignConfig, new_seed
from conformance.harness.target import Target

TARGET = Target("127.0.0.1", 9004)


@pytest.mark.parametrize(("settings", "message"), [
    ({"capture": "some"}, "capture must be failures, all or off"),
    ({"stateful_share": 1.5}, "the stateful share must be between 0 and 1"),
    ({"stateful_share": -0.1}, "the stateful share must be between 0 and 1"),
    ({"max_examples": 0}, "--max-examples must be at least 1"),
    ({"duration_s": 0.0}, "--duration must be positive"),
    ({"batch": 0}, "batch, liveness interval and chunk size must be at least 1"),
    ({"liveness_every": 0}, "batch, liveness interval and chunk size must be at least 1"),
    ({"chunk_examples": 0}, "batch, liveness interval and chunk size must be at least 1"),
])
def test_bad_settings_are_refused(settings: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError) as exc:
        CampaignConfig(target=TARGET, **settings)
    assert str(exc.value) == message


def test_the_edges_of_each_setting_are_accepted() -> None:
    cfg = CampaignConfig(target=TARGET, capture="all", stateful_share=1.0, max_examples=1, duration_s=0.01, batch=1,
                         liveness_every=1, chunk_examples=1)
    assert (cfg.capture, cfg.stateful_share, cfg.max_examples) == ("all", 1.0, 1)
    assert CampaignConfig(target=TARGET, stateful_share=0.0, capture="off").stateful_share == 0.0


def test_a_new_seed_is_a_positive_32_bit_number() -> None:
    seeds = {new_seed() for _ in range(20)}
    assert all(1 <= s < 2**32 for s in seeds) and len(seeds) > 1
