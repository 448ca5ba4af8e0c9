"""Suite settings: every option defined once, resolved in one place.

The pytest plugin adds these options to its ``isight`` group and ``isight-conformance
run`` adds the same ones to argparse; :meth:`SuiteSettings.resolve` is the only code
that turns option values into settings (and the only place defaults live).

``run`` hands the resolved settings to pytest as an object (:class:`SettingsPlugin`), and the
xdist controller hands them to its workers serialised once (:meth:`SuiteSettings.to_dict`):
they are not written back to flags and parsed again.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from ..harness.target import Target
from ..i18n import N_, gettext
from ..protocol import DEFAULT_PORT, Profile
from .profile_options import add_profile_options, profile_from_options

#: (flag, argparse/pytest keyword arguments); dests all start with "isight_".
SUITE_OPTIONS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("--target", {"dest": "isight_target", "metavar": "HOST:PORT", "default": None,
                  "help": N_("the AI Box to test over TCP (default: start the bundled reference box); under pytest it "
                          "may be given several times: every case runs against each box, one report per box")}),
    ("--udp-target", {"dest": "isight_udp_target", "metavar": "HOST:PORT", "default": None,
                      "help": N_("the box's UDP endpoint; UDP cases are SKIP without it")}),
    ("--stream-target", {"dest": "isight_stream_target", "metavar": "HOST:PORT", "default": None,
                         "help": N_("where the pose stream connects (default: same as --target)")}),
    ("--extension", {"dest": "isight_extension", "choices": ["auto", "on", "off"], "default": None,
                     "help": N_("extension E (actions 26/27): detect once (auto, default), force on, or skip")}),
    ("--report-dir", {"dest": "isight_report_dir", "metavar": "DIR", "default": None,
                      "help": N_("write summary.json, junit.xml and report.html here")}),
    ("--pcap-dir", {"dest": "isight_pcap_dir", "metavar": "DIR", "default": None,
                    "help": N_("write one pcapng per case here")}),
    ("--capture", {"dest": "isight_capture", "choices": ["synth", "live", "off"], "default": None,
                   "help": N_("pcaps synthesised from the socket transcript (synth, default), captured "
                           "from the interface (live, needs root), or none (off)")}),
    ("--stream-seconds", {"dest": "isight_stream_seconds", "type": float, "metavar": "S", "default": None,
                          "help": N_("how long the timing cases stream poses (default 3)")}),
    ("--settle-ms", {"dest": "isight_settle_ms", "type": int, "metavar": "MS", "default": None,
                     "help": N_("after a probe's answer, how long to watch for late extra answers (default 50)")}),
    ("--sequence", {"dest": "isight_sequences", "action": "append", "metavar": "FILE", "default": None,
                    "help": N_("also run this scripted sequence file (repeatable)")}),
    ("--cases", {"dest": "isight_cases", "action": "append", "metavar": "GLOB", "default": None,
                 "help": N_("run only cases whose ID matches GLOB (repeatable), e.g. 'F*' or 'A3-*'")}),
    ("--exclude", {"dest": "isight_exclude", "action": "append", "metavar": "GLOB", "default": None,
                   "help": N_("leave out cases whose ID matches GLOB (repeatable)")}),
    ("--target-label", {"dest": "isight_target_label", "metavar": "LABEL", "default": None,
                        "help": N_("how reports name the target")}),
    ("--seed", {"dest": "isight_seed", "type": int, "metavar": "N", "default": None,
                "help": N_("seed of the fuzz cases FUZZ-01/02 (default 20240601; a run is repeatable with its seed)")}),
)
#: FUZZ-01/02's seed when --seed is not given.
DEFAULT_SEED = 20240601


@dataclasses.dataclass(frozen=True)
class SuiteSettings:
    target: Target | None = None  # None: start the bundled reference box
    #: every box to test (pytest: ``--target`` given several times); ``target`` is the first
    targets: tuple[Target, ...] = ()
    udp_target: Target | None = None
    stream_target: Target | None = None
    profile: Profile = dataclasses.field(default_factory=Profile)
    extension: str = "auto"
    report_dir: Path | None = None
    pcap_dir: Path | None = None
    capture: str = "synth"
    stream_seconds: float = 3.0
    settle_s: float = 0.05
    sequences: tuple[Path, ...] = ()
    target_label: str = ""
    cases: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    seed: int = DEFAULT_SEED

    def selects(self, case_id: str) -> bool:
        """--cases / --exclude, by glob on the case ID (a parametrised ID also matches its base)."""
        base = case_id.split("[", 1)[0]
        names = (case_id, base)

        def hit(glob: str) -> bool:  # an exact ID (brackets and all) or a glob
            return glob in names or any(fnmatch.fnmatchcase(n, glob) for n in names)

        if self.cases and not any(hit(g) for g in self.cases):
            return False
        return not any(hit(g) for g in self.exclude)

    @property
    def time_out_s(self) -> float:
        """T1's bound in seconds (the profile's)."""
        return self.profile.time_out_s

    @classmethod
    def resolve(cls, get: Callable[[str], Any]) -> SuiteSettings:
        """Settings from option values (``get(dest)``); raises ValueError with a clear message."""

        def target(dest: str) -> Target | None:
            text = get(dest)
            return Target.parse(text, DEFAULT_PORT) if text else None

        given = get("isight_target")
        targets = tuple(Target.parse(t, DEFAULT_PORT) for t in ([given] if isinstance(given, str) else given or ()))
        if len(set(targets)) != len(targets):
            raise ValueError("--target: the same box is named twice")

        stream_seconds = get("isight_stream_seconds")
        settle = get("isight_settle_ms")
        if stream_seconds is not None and not 0.2 <= stream_seconds <= 3600:
            raise ValueError("--stream-seconds must be between 0.2 and 3600")
        if settle is not None and not 0 <= settle <= 10_000:
            raise ValueError("--settle-ms must be between 0 and 10000")
        sequences = tuple(Path(p) for p in (get("isight_sequences") or ()))
        for path in sequences:
            if not path.is_file():
                raise ValueError(f"--sequence {path}: no such file")
        report_dir, pcap_dir = get("isight_report_dir"), get("isight_pcap_dir")
        return cls(
            target=targets[0] if targets else None,
            targets=targets,
            udp_target=target("isight_udp_target"),
            stream_target=target("isight_stream_target"),
            profile=profile_from_options(get),
            extension=get("isight_extension") or "auto",
            report_dir=Path(report_dir) if report_dir else None,
            pcap_dir=Path(pcap_dir) if pcap_dir else None,
            capture=get("isight_capture") or "synth",
            stream_seconds=stream_seconds if stream_seconds is not None else 3.0,
            settle_s=(settle if settle is not None else 50) / 1000,
            sequences=sequences,
            target_label=get("isight_target_label") or "",
            cases=tuple(get("isight_cases") or ()),
            exclude=tuple(get("isight_exclude") or ()),
            seed=get("isight_seed") if get("isight_seed") is not None else DEFAULT_SEED,
        )

    # -- handed over as an object: to the plugin (SettingsPlugin), to xdist workers (serialised once) --------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; :meth:`from_dict` gives these settings back (an xdist worker's copy)."""

        def target(t: Target | None) -> list[Any] | None:
            return None if t is None else [t.host, t.port]

        return {
            "target": target(self.target), "targets": [target(t) for t in self.targets],
            "udp_target": target(self.udp_target), "stream_target": target(self.stream_target),
            "profile": self.profile.to_dict(), "extension": self.extension,
            "report_dir": None if self.report_dir is None else str(self.report_dir),
            "pcap_dir": None if self.pcap_dir is None else str(self.pcap_dir),
            "capture": self.capture, "stream_seconds": self.stream_seconds, "settle_s": self.settle_s,
            "sequences": [str(p) for p in self.sequences], "target_label": self.target_label,
            "cases": list(self.cases), "exclude": list(self.exclude), "seed": self.seed,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SuiteSettings:
        def target(pair: list[Any] | None) -> Target | None:
            return None if pair is None else Target(str(pair[0]), int(pair[1]))

        def path(text: str | None) -> Path | None:
            return None if text is None else Path(text)

        return cls(
            target=target(data["target"]), targets=tuple(Target(str(h), int(p)) for h, p in data["targets"]),
            udp_target=target(data["udp_target"]), stream_target=target(data["stream_target"]),
            profile=Profile.from_dict(data["profile"]), extension=data["extension"],
            report_dir=path(data["report_dir"]), pcap_dir=path(data["pcap_dir"]), capture=data["capture"],
            stream_seconds=data["stream_seconds"], settle_s=data["settle_s"],
            sequences=tuple(Path(p) for p in data["sequences"]), target_label=data["target_label"],
            cases=tuple(data["cases"]), exclude=tuple(data["exclude"]), seed=data["seed"],
        )


class SettingsPlugin:
    """Resolved settings handed to pytest as an object: ``pytest.main(args, plugins=[SettingsPlugin(settings)])``.

    The isight plugin takes them as they are (:func:`handed_settings`) instead of parsing its flags;
    ``pytest --pyargs conformance.cases --target ...`` (no object) still resolves its flags."""

    def __init__(self, settings: SuiteSettings) -> None:
        self.settings = settings


#: the controller's settings in an xdist worker's ``workerinput``: JSON, serialised once (:meth:`SuiteSettings.to_dict`)
WORKER_INPUT = "isight_settings"


def handed_settings(plugins: Iterable[object], workerinput: Mapping[str, Any] | None = None) -> SuiteSettings | None:
    """The settings handed over as an object: on an xdist worker its controller's (``workerinput``), else
    those a :class:`SettingsPlugin` among ``plugins`` carries (None: none were handed over)."""
    sent = (workerinput or {}).get(WORKER_INPUT)
    if sent:
        return SuiteSettings.from_dict(json.loads(sent))
    return next((p.settings for p in plugins if isinstance(p, SettingsPlugin)), None)


#: pytest owns these flags; under pytest the suite's options take another name.
PYTEST_RENAMES = {"--capture": "--isight-capture"}


def add_suite_options(add: Callable[..., Any], pytest: bool = False) -> None:
    """Register the suite options and the profile options (argparse's add_argument,
    or pytest's addoption with ``pytest=True``, where ``--target`` may repeat)."""
    for flag, kwargs in SUITE_OPTIONS:
        # translated in the language active when the parser is built; the text is read out of the dict first so
        # that no string literal sits inside gettext() (Babel <= 2.18 extracted the key "help" as a message)
        text = kwargs["help"]
        kwargs = {**kwargs, "help": gettext(text)}
        if pytest and flag == "--target":
            kwargs = {**kwargs, "action": "append"}
        add(PYTEST_RENAMES.get(flag, flag) if pytest else flag, **kwargs)
    add_profile_options(add)
