"""What report.html's first page shows of an acceptance: the run ID (also in every printed page's footer), the
device under test, the tester, the manifest's hash and the declared / observed table.

The acceptance arrives as the plain dict summary.json holds (:meth:`conformance.acceptance.record.Acceptance.to_dict`),
so the report writers do not depend on how it was made.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from markupsafe import Markup

from ..i18n import N_, _
from .html_cases import pcap_href

#: the manifest's hash goes here once the package is sealed (conformance.acceptance.manifest.SLOT)
MANIFEST_PLACEHOLDER = "0" * 64

DUT_LABELS = {
    "vendor": N_("Vendor"), "model": N_("Model"), "firmware": N_("Firmware"), "serial": N_("Serial number"),
    "hardware": N_("Hardware revision"), "site": N_("Site"), "operator": N_("Operator"), "witness": N_("Witness"),
}
IDENTITY = ("vendor", "model", "firmware", "serial")
STATUS_WORDS = {
    "confirmed": N_("confirmed"),
    "contradicted": N_("contradicted"),
    "not exercised": N_("not exercised"),
    "inferred": N_("inferred"),
}
STATUS_CLASS = {"confirmed": "v-PASS", "contradicted": "v-FAIL", "not exercised": "v-SKIP", "inferred": "v-INFORMATIONAL"}


def _tester_rows(tester: dict[str, Any]) -> list[tuple[str, str]]:
    libraries = tester.get("libraries") or {}
    return [
        (_("Suite version"), f"{tester.get('suite', 'isight-conformance')} {tester.get('version', '')}"),
        (_("Git commit"), str(tester.get("git_commit", ""))),
        (_("Python"), str(tester.get("python", ""))),
        (_("Operating system"), str(tester.get("os", ""))),
        (_("Host"), str(tester.get("host", ""))),
        (_("Libraries"), ", ".join(f"{name} {version}" for name, version in libraries.items())),
        (_("Clause registry version"), str(tester.get("clause_registry_version", ""))),
        (_("PROTOCOL.md judged against (SHA-256)"), str(tester.get("protocol_md_sha256", ""))),
    ]


def _row_view(row: dict[str, Any], report_dir: Path, pcap_base: Path | None) -> dict[str, Any]:
    status = str(row.get("status", ""))
    pcap = row.get("pcap")
    observed, note = row.get("observed"), str(row.get("note") or "")
    return {**row, "label": _(str(row.get("label", ""))), "status_word": _(STATUS_WORDS.get(status, status)),
            "observed": _(observed) if isinstance(observed, str) and observed else observed,
            "note": _(note) if note else "",
            "cls": STATUS_CLASS.get(status, "v-none"),
            "pcap_href": pcap_href(pcap, report_dir, pcap_base) if pcap else None}


def acceptance_view(acceptance: dict[str, Any] | None, report_dir: Path, pcap_base: Path | None) -> dict[str, Any] | None:
    """The first page's acceptance block (None: the run made no acceptance package)."""
    if not acceptance:
        return None
    dut = acceptance.get("dut") or {}
    declaration = acceptance.get("declaration") or None
    return {
        "run_id": acceptance.get("run_id", ""),
        "dut": [(_(DUT_LABELS.get(k, k)), v) for k, v in dut.items()],
        "dut_missing": [_(DUT_LABELS[k]) for k in IDENTITY if k not in dut],
        "tester": _tester_rows(acceptance.get("tester") or {}),
        "manifest_placeholder": MANIFEST_PLACEHOLDER,
        "outside": list(acceptance.get("outside_package") or []),
        "declared": declaration is not None,
        "declared_file": (declaration or {}).get("file", ""),
        "declared_source": (declaration or {}).get("source", ""),
        "declared_by": (declaration or {}).get("declared_by", ""),
        "rows": [_row_view(r, report_dir, pcap_base) for r in acceptance.get("declared_observed") or []],
    }


def page_footer(acceptance: dict[str, Any] | None) -> Markup:
    """The printed page footer's left part (a CSS string): the report's name and, for a package, its run ID."""
    words = _("iSight conformance report")
    if acceptance and acceptance.get("run_id"):
        words += " · " + _("run {run_id}").format(run_id=acceptance["run_id"])
    return Markup('"' + words.replace("\\", "").replace('"', "'") + '"')
