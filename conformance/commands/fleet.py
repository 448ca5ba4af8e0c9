"""``isight-conformance run --targets FILE [--jobs N]``: a fleet run (``run``'s handler hands it over).

Reads and checks the fleet file (exit 2 and one line naming the line for a bad one),
then :func:`~conformance.fleet.fleet_run.run_fleet` runs one ``run`` child per box, ``--jobs``
at a time, shows boxes done / total, and writes ``fleet.json`` and ``fleet.html`` once, at the end, into the fleet directory
(``--report-dir DIR``, default ``reports/fleet-<stamp>``), then seals that directory with a ``manifest.json``
(each box's own package inside it is sealed by its run). Exit status: 0 when every
box passed (no FAIL/ERROR, or exactly its expected failures), 1 otherwise or when the
run was stopped (Ctrl-C, SIGTERM: fleet.json still covers the boxes that finished),
2 for a bad fleet file or bad options.
"""

from __future__ import annotations

import argparse
import uuid
from pathlib import Path

from ..acceptance.manifest import load, seal
from ..fleet.children import BoxRun
from ..fleet.fleet_run import run_fleet, usage_error
from ..fleet.spec import FleetFileError, command_line_overrides, load_fleet
from ..report.rundirs import default_run_dirs

#: run options that make no sense next to --targets (the fleet file says them per box)
CONFLICTS = (("isight_target", "--target"), ("isight_udp_target", "--udp-target"),
             ("isight_stream_target", "--stream-target"), ("expected_failures", "--expected-failures"),
             ("list", "--list"))


def main_fleet(args: argparse.Namespace) -> int:
    jobs = getattr(args, "jobs", None)
    jobs = 1 if jobs is None else jobs
    if jobs < 1:
        return usage_error("--jobs must be at least 1")
    for dest, flag in CONFLICTS:
        if getattr(args, dest, None):
            return usage_error(f"{flag} does not go with --targets: give it per box in the fleet file")
    try:
        spec = load_fleet(args.targets, command_line_overrides(args))
    except FleetFileError as exc:
        return usage_error(str(exc))
    except ValueError as exc:  # a bad value on the command line
        return usage_error(str(exc))
    except OSError as exc:
        return usage_error(f"cannot read the fleet file {args.targets}: {exc.strerror or exc}")
    try:
        fleet_dir, _ = default_run_dirs(getattr(args, "isight_report_dir", None), None, pcaps=False, prefix="fleet-")
        fleet_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return usage_error(f"cannot create the fleet directory: {exc}")
    pcap_base = getattr(args, "isight_pcap_dir", None)
    runs = [BoxRun(box, fleet_dir / box.name,
                   Path(pcap_base) / box.name if pcap_base else fleet_dir / box.name / "pcaps")
            for box in spec.boxes]
    code = run_fleet(spec, runs, fleet_dir, jobs, quiet=bool(getattr(args, "quiet", False)))
    if (fleet_dir / "fleet.json").is_file():  # one package: every box's and the fleet's
        for box in runs:  # sealed again: the run's own log (run.log) was still being written when it sealed
            if (box.report_dir / "manifest.json").is_file():
                seal(box.report_dir, str(load(box.report_dir)[0].get("run_id", "")))
        print(f"manifest: {fleet_dir / 'manifest.json'} (sha256 {seal(fleet_dir, str(uuid.uuid4()))})")
    return code
