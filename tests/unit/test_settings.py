"""conformance/runtime/settings.py: the resolved settings travel as an object. ``to_dict``/``from_dict`` is
the one serialisation (an xdist worker's copy), and ``handed_settings`` finds the object ``run`` hands to
``pytest.main``."""

from __future__ import annotations

import json
from pathlib import Path

from conformance.harness.target import Target
from conformance.protocol import Profile
from conformance.runtime.settings import SettingsPlugin, SuiteSettings, handed_settings


def test_settings_survive_their_serialisation_unchanged() -> None:
    settings = SuiteSettings(
        target=Target("::1", 9004), targets=(Target("::1", 9004), Target("127.0.0.1", 9005)),
        udp_target=Target("127.0.0.1", 9006), stream_target=Target("localhost", 9007),
        profile=Profile(first_index=1, byte_order="little", crc="xmodem", time_out_ms=1234, tcp_check="zero",
                        pose_rate_hz=12.5, strict=False),
        extension="off", report_dir=Path("/tmp/r"), pcap_dir=None, capture="off", stream_seconds=0.5,
        settle_s=0.125, sequences=(Path("a.seq"),), target_label="bench", cases=("F*", "A3-01"),
        exclude=("FUZZ-*",), seed=7)
    back = SuiteSettings.from_dict(json.loads(json.dumps(settings.to_dict())))
    assert back == settings
    assert SuiteSettings.from_dict(json.loads(json.dumps(SuiteSettings().to_dict()))) == SuiteSettings()


def test_the_handed_settings_are_found_among_the_plugins() -> None:
    settings = SuiteSettings(seed=3)
    assert handed_settings([object(), SettingsPlugin(settings)]) is settings
    assert handed_settings([object()]) is None


def test_the_profile_gives_its_bounds_in_seconds() -> None:
    profile = Profile(time_out_ms=1500, vision_time_out_ms=250)
    assert profile.time_out_s == 1.5 and profile.vision_time_out_s == 0.25
    assert profile.answer_bound_s(0x27) == 0.25 and profile.answer_bound_s(0x01) == 1.5
    assert profile.answer_bound_s(None) == 1.5
    assert SuiteSettings(profile=profile).time_out_s == 1.5
