"""summary.json, and what every report derives from the results.

Every writer (JSON, JUnit, HTML, terminal) takes its totals, its per-clause verdicts
and its overall line from here, so the reports can never disagree with each other.
Files are written atomically (a temp file in the same directory, then
``os.replace``): an interrupted run leaves the previous report or none, never half a one.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..i18n import _, current
from ..model.verdicts import VERDICT_ORDER, CaseResult, Level, RootCause, SuiteInfo, Verdict
from ..protocol.clauses import REGISTRY_VERSION, all_clauses, families

#: Every clause of docs/PROTOCOL.md, in document order, with its short title for tables:
#: a view of the clause registry (conformance/protocol/clauses.json).
CLAUSES: dict[str, str] = {c.id: c.title for c in all_clauses().values()}

#: Clause families, in document order (from the registry).
FAMILIES: dict[str, str] = families()

_RANK = {v: i for i, v in enumerate(VERDICT_ORDER)}


def registry_version() -> str:
    """The version of the clause registry the verdicts cite."""
    return REGISTRY_VERSION


def worst(verdicts: Iterable[Verdict]) -> Verdict | None:
    """The worst verdict (first in VERDICT_ORDER), or None for none."""
    return min(verdicts, key=_RANK.__getitem__, default=None)


def rank(verdict: Verdict) -> int:
    """Position in VERDICT_ORDER: 0 is the worst."""
    return _RANK[verdict]


def totals(cases: Iterable[CaseResult]) -> dict[str, int]:
    """Count per verdict value, every verdict present (zeros included), worst first."""
    counts = {v.value: 0 for v in VERDICT_ORDER}
    for case in cases:
        counts[case.verdict.value] += 1
    return counts


@dataclass(frozen=True)
class ClauseResult:
    clause: str
    title: str  # short title ("" for a clause PROTOCOL.md does not have)
    verdict: Verdict | None  # worst over its cases; None: not tested
    cases: tuple[str, ...]  # case ids, in run order
    levels: dict[Level, Verdict]  # worst verdict among the cases of each level

    @property
    def tested(self) -> bool:
        return self.verdict is not None


def _clause_key(clause: str) -> tuple[int, str, int, str]:
    family = list(FAMILIES).index(clause[0]) if clause[:1] in FAMILIES else len(FAMILIES)
    m = re.match(r"^([A-Za-z]*)(\d*)(.*)$", clause)
    assert m is not None  # the pattern matches any string
    return family, m.group(1), int(m.group(2) or 0), m.group(3)


def by_clause(cases: Iterable[CaseResult]) -> dict[str, ClauseResult]:
    """Every clause of PROTOCOL.md (untested ones with verdict None), then any other
    clause a case names, each with its worst verdict and the ids of the cases that test it.

    A FAIL or NON-STRICT marks only the clause(s) it judged (``case.judged``), at the
    level of the verdict: a case about A2 that fails R2 marks R2, not A2."""
    ids: dict[str, list[str]] = {c: [] for c in CLAUSES}
    verdicts: dict[str, list[tuple[Level, Verdict]]] = {c: [] for c in CLAUSES}
    for case in cases:
        judged = set(case.judged) if case.verdict in (Verdict.FAIL, Verdict.NON_STRICT) else set()
        for clause in dict.fromkeys(case.clauses):  # a clause named twice counts once
            ids.setdefault(clause, []).append(case.id)
            if judged and clause not in judged:
                continue  # tested by the case, but not what its verdict is about
            level = {Verdict.FAIL: Level.MUST, Verdict.NON_STRICT: Level.SHOULD}.get(case.verdict, case.level) \
                if judged else case.level
            verdicts.setdefault(clause, []).append((level, case.verdict))
    out: dict[str, ClauseResult] = {}
    for clause in sorted(ids, key=_clause_key):
        levels: dict[Level, Verdict] = {}
        for level in Level:
            w = worst(v for lv, v in verdicts[clause] if lv is level)
            if w is not None:
                levels[level] = w
        out[clause] = ClauseResult(clause, CLAUSES.get(clause, ""), worst(v for _, v in verdicts[clause]),
                                   tuple(ids[clause]), levels)
    return out


def family_of(case: CaseResult) -> str:
    """The family letter of a case's first clause ("F" for F3), or "other"."""
    first = case.clauses[0] if case.clauses else ""
    return first[0] if first[:1].isalpha() else "other"


# -- the overall line --------------------------------------------------------------
def conforms(cases: Iterable[CaseResult]) -> bool:
    """True when no case is FAIL or ERROR (and at least one case was judged)."""
    t = totals(cases)
    return t["FAIL"] == 0 and t["ERROR"] == 0 and _judged(t) > 0


def _judged(t: dict[str, int]) -> int:
    return t["PASS"] + t["NON-STRICT"] + t["INFORMATIONAL"] + t["FAIL"]


def overall_line(cases: Iterable[CaseResult], suite: SuiteInfo | None = None) -> str:
    """The one-line result an integrator signs, e.g.
    ``DOES NOT CONFORM: 2 FAIL, 0 ERROR; 1 NON-STRICT`` or
    ``CONFORMS (no FAIL/ERROR); 0 NON-STRICT; 3 INCONCLUSIVE (not judged)``.

    A run in which no case reached a judgement (nothing ran, or everything was
    SKIP/INCONCLUSIVE) says NOT JUDGED rather than CONFORMS. A run cut short
    (``suite.complete`` is False) says ``INCOMPLETE (k of n cases run)``, never CONFORMS.
    In the active language (:mod:`conformance.i18n`); the verdict names stay as they are.
    """
    cases = list(cases)
    t = totals(cases)
    n = {"fail": t["FAIL"], "error": t["ERROR"], "nonstrict": t["NON-STRICT"], "skip": t["SKIP"],
         "inconclusive": t["INCONCLUSIVE"]}
    if suite is not None and not suite.complete:
        line = _("INCOMPLETE ({run} of {total} cases run)").format(run=len(cases),
                                                                   total=max(suite.cases_total, len(cases)))
        if t["FAIL"] or t["ERROR"]:
            line += _(": DOES NOT CONFORM so far: {fail} FAIL, {error} ERROR").format(**n)
        return line + _("; {nonstrict} NON-STRICT").format(**n)
    if t["FAIL"] or t["ERROR"]:
        line = _("DOES NOT CONFORM: {fail} FAIL, {error} ERROR").format(**n)
    elif not _judged(t):
        not_judged = t["SKIP"] + t["INCONCLUSIVE"]
        return (_("NOT JUDGED: no case reached a verdict ({skip} SKIP, {inconclusive} INCONCLUSIVE)").format(**n)
                if not_judged else _("NOT JUDGED: no case ran"))
    else:
        line = _("CONFORMS (no FAIL/ERROR)")
    line += _("; {nonstrict} NON-STRICT").format(**n)
    if t["INCONCLUSIVE"]:
        line += _("; {inconclusive} INCONCLUSIVE (not judged)").format(**n)
    return line


def overall_state(cases: Iterable[CaseResult], suite: SuiteInfo | None = None) -> str:
    """"conforms", "fails", "incomplete" or "unjudged": what colour the overall line gets."""
    t = totals(cases)
    if t["FAIL"] or t["ERROR"]:
        return "fails"
    if suite is not None and not suite.complete:
        return "incomplete"
    return "conforms" if _judged(t) else "unjudged"


# -- text helpers shared by the writers ---------------------------------------------
# XML 1.0 forbids C0 controls (but tab, LF, CR), surrogates and U+FFFE/FFFF; DEL and
# C1 controls are legal but invisible. All of them are shown as escapes instead.
_UNSAFE = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")


def _escape_char(m: re.Match[str]) -> str:
    code = ord(m.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def clean_text(text: Any) -> str:
    """``text`` as a string that any report format can carry: control characters,
    lone surrogates and non-characters become visible ``\\xNN`` / ``\\uNNNN`` escapes."""
    s = text if isinstance(text, str) else str(text)
    return _UNSAFE.sub(_escape_char, s) if _UNSAFE.search(s) else s


def one_line(text: Any, limit: int = 500) -> str:
    """``clean_text`` on one line (whitespace runs collapsed), cut to ``limit`` characters."""
    s = " ".join(clean_text(text).split())
    return s if len(s) <= limit else s[: limit - 1] + "…"


_HEX_NOISE = re.compile(r"[\s:.\-]|0x", re.IGNORECASE)
_HEX = re.compile(r"^(?:[0-9a-fA-F]{2})*$")


def hex_bytes(text: str) -> list[str] | None:
    """``"FE FE:00 01"`` -> ``["fe", "fe", "00", "01"]``; None when it is not hex."""
    compact = _HEX_NOISE.sub("", text or "")
    if not _HEX.match(compact):
        return None
    return [compact[i : i + 2].lower() for i in range(0, len(compact), 2)]


def group_hex(text: str, per_line: int = 16, limit: int | None = None) -> str:
    """Hex as space-separated bytes, ``per_line`` bytes per line (0: one line).

    Text that is not hex comes back cleaned but otherwise as it was. With ``limit``,
    only the first ``limit`` bytes are shown and a note says how many there were.
    """
    octets = hex_bytes(text)
    if octets is None:
        return clean_text(text)
    shown = octets if limit is None else octets[:limit]
    if per_line:
        out = "\n".join(" ".join(shown[i : i + per_line]) for i in range(0, len(shown), per_line))
    else:
        out = " ".join(shown)
    if len(shown) < len(octets):
        out += f"{chr(10) if per_line else ' '}… ({len(octets)} bytes in all, first {len(shown)} shown)"
    return out


def format_duration(seconds: float) -> str:
    """``0.0123`` -> ``12 ms``, ``12.34`` -> ``12.3 s``, ``3723`` -> ``1 h 02 min 03 s``."""
    if seconds < 1:
        return f"{seconds * 1000:.0f} ms"
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, secs = divmod(int(round(seconds)), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min {secs:02d} s" if hours else f"{minutes} min {secs:02d} s"


# -- files ---------------------------------------------------------------------------
def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same directory, fsync,
    ``os.replace``), creating the directory if needed. Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def suite_dict(suite: SuiteInfo) -> dict[str, Any]:
    """SuiteInfo as summary.json's "suite" object (its fields, in their order), with the
    clause registry's version filled in when the run did not set it, and ``lang``: the language the
    reports were written in (keys and machine values stay English)."""
    out = dataclasses.asdict(suite)
    if not out.get("registry_version"):
        out["registry_version"] = registry_version()
    out["lang"] = current()
    return out


def write_summary(path: str | os.PathLike[str], suite: SuiteInfo, cases: list[CaseResult],
                  root_causes: Sequence[RootCause] = (), acceptance: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write summary.json atomically and return what was written:
    ``{"suite": {...SuiteInfo}, "root_causes": [...], "cases": [CaseResult.to_summary()...], "totals": {verdict: n}}``
    and, for a run that made an acceptance package, ``"acceptance"``: run ID, device under test, tester,
    declaration and the declared / observed table."""
    doc: dict[str, Any] = {"suite": suite_dict(suite), "root_causes": [r.to_dict() for r in root_causes],
                           "cases": [c.to_summary() for c in cases], "totals": totals(cases)}
    if acceptance is not None:
        doc["acceptance"] = acceptance
    text = json.dumps(doc, indent=2, ensure_ascii=False, default=_json_default) + "\n"
    # a lone surrogate from hostile input becomes a JSON \udcxx escape, still valid JSON
    atomic_write_bytes(path, text.encode("utf-8", "backslashreplace"))
    return json.loads(text)  # exactly what was written (profile enums as strings etc.)


def _json_default(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    if isinstance(value, bytes):
        return value.hex()
    return str(value)
