"""What a run hands its reports for an acceptance: the run ID, the device under test, the tester, the vendor's
declaration and, once the cases ran, the declared / observed table.

``run`` (and the other commands that write a package) add the options with :func:`add_acceptance_options`,
make an :class:`Acceptance` with :func:`from_args` before anything starts (a bad ``--dut`` or ``--declared`` is
a usage error, exit 2), and the report writers take :meth:`Acceptance.to_dict` (summary.json's ``acceptance``,
report.html's first page).
"""

from __future__ import annotations

import argparse
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..i18n import _
from ..model.verdicts import CaseResult
from ..report.summary import atomic_write_bytes
from . import declared_table
from .declaration import PACKAGE_COPY, Declaration, read
from .dut import resolve_dut
from .manifest import seal
from .tester import identity


@dataclass(frozen=True)
class Acceptance:
    run_id: str
    tester: dict[str, Any]
    dut: dict[str, str] = field(default_factory=dict)
    declaration: Declaration | None = None
    #: the declared / observed rows (:func:`~.declared_table.table`), filled once the cases ran
    rows: tuple[dict[str, Any], ...] = ()

    def judged(self, cases: Sequence[CaseResult], suite: dict[str, Any]) -> tuple[Acceptance, list[CaseResult]]:
        """This acceptance with its declared / observed table, and a FAIL case per contradicted declaration."""
        rows = declared_table.table(self.declaration, cases, suite)
        return replace(self, rows=tuple(rows)), declared_table.findings(rows)

    def to_dict(self) -> dict[str, Any]:
        return {"run_id": self.run_id, "dut": dict(self.dut), "tester": dict(self.tester),
                "declaration": self.declaration.to_dict() if self.declaration else None,
                "declared_observed": [{k: v for k, v in row.items() if k not in ("sent_hex", "received_hex")}
                                      for row in self.rows],
                "table_source": "declared" if self.declaration else "inferred"}


def new(dut: dict[str, str] | None = None, declaration: Declaration | None = None) -> Acceptance:
    return Acceptance(str(uuid.uuid4()), identity(), dict(dut or {}), declaration)


def add_acceptance_options(add: Callable[..., Any], declared: bool = True) -> None:
    """``--dut``, ``--dut-file`` and (for a run that tests a box) ``--declared`` (argparse's add_argument)."""
    add("--dut", metavar="KEY=VALUE,...", default=None,
        help=_("the device under test: vendor=…,model=…,firmware=…,serial=… (also hardware, site, operator, "
               "witness); shown on the report's first page and in summary.json"))
    add("--dut-file", metavar="FILE", default=None,
        help=_("the device under test from a TOML file (the same keys; --dut wins over it)"))
    if not declared:
        return
    add("--declared", metavar="FILE", default=None,
        help=_("the vendor's declaration (TOML, docs/DECLARED.md): the run is judged under the declared profile "
               "and the report shows declared / observed"))


def seal_package(report_dir: Path, acceptance: Acceptance | None) -> str:
    """Write the package's ``manifest.json`` (after every other file of it) and put its hash on report.html;
    the hash ("" when the run wrote no summary.json, so no package)."""
    if acceptance is None or not (report_dir / "summary.json").is_file():
        return ""
    if acceptance.declaration is not None and acceptance.declaration.text:  # the declaration as the vendor wrote it
        atomic_write_bytes(report_dir / PACKAGE_COPY, acceptance.declaration.text.encode("utf-8"))
    return seal(report_dir, acceptance.run_id)


def from_args(args: argparse.Namespace) -> Acceptance:
    """The acceptance the command line asks for (ValueError: a bad --dut, --dut-file or --declared)."""
    dut = resolve_dut(getattr(args, "dut", None), getattr(args, "dut_file", None))
    declared = getattr(args, "declared", None)
    return new(dut, read(Path(declared)) if declared else None)
