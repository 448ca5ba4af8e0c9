"""``isight-conformance clauses [ID...]``: the clauses of docs/PROTOCOL.md from the registry.

Prints each clause's level, title, text, the flags that touch it and where the source
document speaks to it; ``--format json`` for tools. An ID may be a family letter
(``B`` is B1..B5). An unknown ID is one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import textwrap
from collections.abc import Sequence

from ..i18n import N_, _, current, wrap_cells
from ..model.exit_codes import EXIT_OK, EXIT_USAGE
from ..protocol.clauses import REGISTRY_VERSION, Clause, all_clauses, families
from .registry import Command

WIDTH = 88


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("ids", nargs="*", metavar="ID", help=_("clause IDs (F1 ... E5) or family letters (F, B, A, S, T, R, E)"))
    p.add_argument("--format", choices=("text", "json"), default="text", help=_("plain text (default) or JSON"))
    p.add_argument("--brief", action="store_true", help=_("text: one line per clause (ID, level, title)"))


def select(ids: Sequence[str]) -> list[Clause]:
    """The clauses named (each once, in the order asked); all of them for none. KeyError names
    the first unknown ID."""
    every = all_clauses()
    if not ids:
        return list(every.values())
    out: dict[str, Clause] = {}
    for raw in ids:
        key = raw.strip().upper()
        if key in families():
            out.update((c.id, c) for c in every.values() if c.id[0] == key)
        elif key in every:
            out[key] = every[key]
        else:
            raise KeyError(raw)
    return list(out.values())


def format_text(clauses: Sequence[Clause], brief: bool = False) -> str:
    """The clauses as text, titles and texts in the active language (``--lang``)."""
    lang = current()
    if brief:
        return "\n".join(f"{c.id:<3} {'/'.join(c.levels):<11} {c.words(lang)[0]}" for c in clauses)
    blocks = []
    for c in clauses:
        title, text = c.words(lang)
        lines = [f"{c.id}  {', '.join(c.levels)}  {title}"]
        lines += ["    " + line for line in wrap_cells(text, WIDTH - 4)]
        lines.append("    " + _("flags: {flags}").format(flags=" ".join(c.flags) if c.flags else _("(none)")))
        if c.source:
            lines += textwrap.wrap(c.source, WIDTH, initial_indent="    source: ", subsequent_indent="      ",
                                   break_on_hyphens=False)
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def format_json(clauses: Sequence[Clause]) -> str:
    return json.dumps({"version": REGISTRY_VERSION, "clauses": [dataclasses.asdict(c) for c in clauses]},
                      ensure_ascii=False, indent=1)


def main_clauses(args: argparse.Namespace) -> int:
    try:
        chosen = select(args.ids)
    except KeyError as exc:
        print(f"isight-conformance clauses: unknown clause {exc.args[0]!r} "
              f"(clauses are F1-F7, B1-B5, A1-A5, S1-S6, T1-T2, R1-R7, E1-E5, or a family letter)", file=sys.stderr)
        return EXIT_USAGE
    out = (format_json(chosen) if args.format == "json" else format_text(chosen, brief=args.brief)) + "\n"
    try:
        sys.stdout.write(out)
    except UnicodeEncodeError:  # a console or pipe in a legacy code page: the quotes are Chinese
        sys.stdout.flush()
        sys.stdout.buffer.write(out.encode("utf-8"))
    return EXIT_OK


COMMAND = Command(
    "clauses", N_("print the clauses of docs/PROTOCOL.md: level, title, text, flags and source"), add_arguments, main_clauses,
    description=N_("Print clauses of the protocol statement (docs/PROTOCOL.md) from the suite's clause registry: "
        "each one's level (MUST broken is FAIL, SHOULD broken NON-STRICT, MAY INFORMATIONAL), title, text, the "
        "flags that change how it is read, and where the source document speaks to it. With no ID, every clause. "
        "Exit status: 0, or 2 for an unknown ID."),
    lang=True,
)
