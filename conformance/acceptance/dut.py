"""The device under test and the people of an acceptance: ``--dut`` and ``--dut-file``.

``--dut vendor=Acme,model=VB-200,firmware=2.1.4,serial=SN0042`` (comma-separated ``key=value``; a value may
hold a comma when the next word is not a known key), or ``--dut-file dut.toml``::

    vendor = "Acme Vision"
    model = "VB-200"
    firmware = "2.1.4"
    serial = "SN0042"
    hardware = "rev C"      # optional
    site = "Plant 3, line 2"
    operator = "A. Tester"
    witness = "B. Witness (integrator)"

(the keys may also sit under a ``[dut]`` table). Keys given on the command line win over the file's.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from ..i18n import N_

#: every key, in the order the report shows them, with its label
FIELDS: dict[str, str] = {
    "vendor": N_("Vendor"),
    "model": N_("Model"),
    "firmware": N_("Firmware"),
    "serial": N_("Serial number"),
    "hardware": N_("Hardware revision"),
    "site": N_("Site"),
    "operator": N_("Operator"),
    "witness": N_("Witness"),
}
#: what names the item tested; an acceptance without them says so
IDENTITY = ("vendor", "model", "firmware", "serial")
MAX_VALUE = 200
_SPLIT = re.compile(r",\s*(?=(?:" + "|".join(FIELDS) + r")\s*=)")


def _value(key: str, value: object, where: str) -> str:
    if key not in FIELDS:
        raise ValueError(f"{where}: unknown key {key!r}; known: {', '.join(FIELDS)}")
    if not isinstance(value, (str, int, float)) or isinstance(value, bool):
        raise ValueError(f"{where}: {key} must be text")
    text = " ".join(str(value).split())
    if not text or len(text) > MAX_VALUE or any(ord(c) < 32 for c in text):
        raise ValueError(f"{where}: {key} must be 1 to {MAX_VALUE} printable characters")
    return text


def parse_dut(text: str) -> dict[str, str]:
    """``vendor=…,model=…`` as a dict (ValueError naming what is wrong)."""
    out: dict[str, str] = {}
    for part in _SPLIT.split(text.strip()):
        key, sep, value = part.partition("=")
        key = key.strip().lower()
        if not sep:
            raise ValueError(f"--dut: expected key=value, got {part!r}")
        if key in out:
            raise ValueError(f"--dut: {key} given twice")
        out[key] = _value(key, value.strip(), "--dut")
    return out


def read_dut_file(path: Path) -> dict[str, str]:
    """A ``dut.toml`` as a dict (ValueError: missing, not TOML, unknown key)."""
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"--dut-file {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"--dut-file {path}: not TOML ({exc})") from None
    table = doc.get("dut", doc) if isinstance(doc.get("dut"), dict) else doc
    return {key: _value(str(key), value, f"--dut-file {path}") for key, value in table.items()}


def resolve_dut(dut: str | None, dut_file: str | None) -> dict[str, str]:
    """The file's keys, then the command line's over them, in :data:`FIELDS` order."""
    found = read_dut_file(Path(dut_file)) if dut_file else {}
    found.update(parse_dut(dut) if dut else {})
    return {key: found[key] for key in FIELDS if key in found}
