"""A fleet run's body: one ``run`` child per box, ``--jobs`` at a time, the boxes done / total,
and ``fleet.json`` and ``fleet.html`` written once, at the end (its handler is
:mod:`conformance.commands.fleet`)."""

from __future__ import annotations

import datetime as _dt
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from ..model.exit_codes import EXIT_USAGE
from .children import BoxRun, FleetRunner, stop_on_signals
from .fleet_page import write_fleet_html
from .fleet_results import box_entry, fleet_document, write_fleet_json
from .spec import FleetSpec

PROG = "isight-conformance run"
STYLE = {"conforms": "green", "expected failures": "green", "fails": "bold red", "error": "bold magenta",
         "interrupted": "yellow", "not run": "dim", "incomplete": "yellow", "unjudged": "yellow"}


def usage_error(message: str) -> int:
    """One line on stderr; the exit status of a usage error."""
    print(f"{PROG}: {message}", file=sys.stderr)
    return EXIT_USAGE


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
        return usage_error(f"cannot write the fleet report: {exc}")
    _print_end(console, doc, fleet_dir)
    if error:
        return usage_error(error)
    if runner.stopped:
        print(f"{PROG}: {runner.stopped}; fleet.json covers the boxes that finished", file=sys.stderr)
    return int(doc["exit_code"])


def _print_end(console: Console, doc: dict[str, Any], fleet_dir: Path) -> None:
    style = "bold green" if doc["passed"] else ("bold yellow" if not doc["complete"] else "bold red")
    console.print(Text(doc["overall"], style=style))
    console.print(Text(f"Fleet report: {fleet_dir / 'fleet.html'}  (and fleet.json); "
                       f"{len(doc['boxes'])} boxes in {doc['duration_s']:.1f} s"))
