"""``isight-conformance run --targets FILE [--jobs N]``: a fleet run.

Reads and checks the fleet file (exit 2 and one line naming the line for a bad one),
runs one ``run`` child per box, ``--jobs`` at a time, shows boxes done / total, and
writes ``fleet.json`` and ``fleet.html`` once, at the end, into the fleet directory
(``--report-dir DIR``, default ``reports/fleet-<stamp>``). Exit status: 0 when every
box passed (no FAIL/ERROR, or exactly its expected failures), 1 otherwise or when the
run was stopped (Ctrl-C, SIGTERM: fleet.json still covers the boxes that finished),
2 for a bad fleet file or bad options.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from ..rundirs import default_run_dirs
from .children import BoxRun, FleetRunner, stop_on_signals
from .html import write_fleet_html
from .results import box_entry, fleet_document, write_fleet_json
from .spec import FleetFileError, FleetSpec, command_line_overrides, load_fleet

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
PROG = "isight-conformance run"
STYLE = {"conforms": "green", "expected failures": "green", "fails": "bold red", "error": "bold magenta",
         "interrupted": "yellow", "not run": "dim", "incomplete": "yellow", "unjudged": "yellow"}
#: run options that make no sense next to --targets (the fleet file says them per box)
CONFLICTS = (("isight_target", "--target"), ("isight_udp_target", "--udp-target"),
             ("isight_stream_target", "--stream-target"), ("expected_failures", "--expected-failures"),
             ("list", "--list"))


def _usage(message: str) -> int:
    print(f"{PROG}: {message}", file=sys.stderr)
    return EXIT_USAGE


def main_fleet(args: argparse.Namespace) -> int:
    jobs = getattr(args, "jobs", None)
    jobs = 1 if jobs is None else jobs
    if jobs < 1:
        return _usage("--jobs must be at least 1")
    for dest, flag in CONFLICTS:
        if getattr(args, dest, None):
            return _usage(f"{flag} does not go with --targets: give it per box in the fleet file")
    try:
        spec = load_fleet(args.targets, command_line_overrides(args))
    except FleetFileError as exc:
        return _usage(str(exc))
    except ValueError as exc:  # a bad value on the command line
        return _usage(str(exc))
    except OSError as exc:
        return _usage(f"cannot read the fleet file {args.targets}: {exc.strerror or exc}")
    try:
        fleet_dir, _ = default_run_dirs(getattr(args, "isight_report_dir", None), None, pcaps=False, prefix="fleet-")
        fleet_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _usage(f"cannot create the fleet directory: {exc}")
    pcap_base = getattr(args, "isight_pcap_dir", None)
    runs = [BoxRun(box, fleet_dir / box.name,
                   Path(pcap_base) / box.name if pcap_base else fleet_dir / box.name / "pcaps")
            for box in spec.boxes]
    return run_fleet(spec, runs, fleet_dir, jobs, quiet=bool(getattr(args, "quiet", False)))


def run_fleet(spec: FleetSpec, runs: list[BoxRun], fleet_dir: Path, jobs: int, quiet: bool = False) -> int:
    console = Console()
    started = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    t0 = time.monotonic()
    live = not quiet and console.is_terminal and not console.is_dumb_terminal
    progress = Progress(TextColumn("[bold]boxes"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                        TextColumn("{task.description}"), console=console, transient=True, disable=not live)
    task = progress.add_task("", total=len(runs))
    done = [0]

    def on_start(run: BoxRun) -> None:
        running = [r.name for r in runs if r.status == "running"]
        progress.update(task, description="running " + ", ".join(running))

    def on_done(run: BoxRun) -> None:
        done[0] += 1
        progress.update(task, advance=1)
        entry = box_entry(run, fleet_dir)
        line = Text()
        line.append(f"[{done[0]}/{len(runs)}] ", style="bold")
        line.append(f"{run.name:<20} ", style="bold")
        line.append(f"{entry['status']:<18}", style=STYLE.get(entry["status"], ""))
        line.append(f" {entry['overall']}" + (f": {entry['message']}" if entry["message"] else "") + "  ")
        line.append(f"({run.duration_s or 0:.1f} s)", style="dim")
        progress.console.print(line, soft_wrap=True, highlight=False)

    print(f"fleet: {len(runs)} boxes from {spec.path}, {jobs} at a time; reports in {fleet_dir}", flush=True)
    runner = FleetRunner(runs, jobs, on_start=on_start, on_done=on_done)
    error: str | None = None
    with progress, stop_on_signals(runner):
        try:
            runner.run()
        except OSError as exc:  # a child could not be started
            error = f"cannot start a box's run: {exc}"
            runner.stop(error)
    doc = fleet_document(runs, fleet_dir, fleet_file=spec.path, jobs=jobs, started=started,
                         duration_s=time.monotonic() - t0, command=shlex.join(sys.argv), stopped=runner.stopped)
    try:
        write_fleet_json(fleet_dir / "fleet.json", doc)
        write_fleet_html(fleet_dir / "fleet.html", doc)
    except OSError as exc:
        return _usage(f"cannot write the fleet report: {exc}")
    _print_end(console, doc, fleet_dir)
    if error:
        return _usage(error)
    if runner.stopped:
        print(f"{PROG}: {runner.stopped}; fleet.json covers the boxes that finished", file=sys.stderr)
    return int(doc["exit_code"])


def _print_end(console: Console, doc: dict[str, Any], fleet_dir: Path) -> None:
    style = "bold green" if doc["passed"] else ("bold yellow" if not doc["complete"] else "bold red")
    console.print(Text(doc["overall"], style=style))
    console.print(Text(f"Fleet report: {fleet_dir / 'fleet.html'}  (and fleet.json); "
                       f"{len(doc['boxes'])} boxes in {doc['duration_s']:.1f} s"))
