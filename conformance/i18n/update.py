"""Update the message catalogues: ``python -m conformance.i18n.update`` (from a source checkout, with Babel).

1. ``pybabel extract``: every string marked with ``_``/``N_``/``ngettext`` in ``conformance/**.py`` and every
   ``{% trans %}``/``_()`` in the Jinja2 templates (``babel.cfg``) into ``locale/isight.pot``;
2. ``pybabel update``: merge it into each ``locale/<ll_CC>/LC_MESSAGES/isight.po`` (new strings arrive with an
   empty translation, strings gone are dropped);
3. ``pybabel compile``: the ``.mo`` files the package reads (entries without a translation are left out, so the
   English text shows).

Then translate the new (empty) entries of the ``.po`` and run it again; ``tests/unit/test_i18n_catalogue.py`` fails
until every string has its translation and the ``.mo`` matches the ``.po``. ``--check`` only reports what is
missing, changing nothing.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

from babel.messages.frontend import CommandLineInterface

from . import DOMAIN, LANGS, LOCALE_DIRS

ROOT = Path(__file__).resolve().parents[2]  # the source checkout
LOCALE = Path(__file__).resolve().parent / "locale"
POT = LOCALE / f"{DOMAIN}.pot"
PROJECT = "isight-conformance"


def pybabel(*args: str) -> None:
    CommandLineInterface().run(["pybabel", "-q", *args])


def extract(output: Path = POT) -> None:
    """The template of every translatable string (stable: sorted, no line numbers). An unchanged template
    is left as it was, so that running the update twice changes no file (not even a date)."""
    with tempfile.TemporaryDirectory() as tmp:
        fresh = Path(tmp) / output.name
        pybabel("extract", "-F", str(ROOT / "babel.cfg"), "--no-location", "--sort-output", "--omit-header",
                "--project", PROJECT, "-o", str(fresh), str(ROOT))
        if not output.exists() or _body(fresh) != _body(output):
            shutil.copyfile(fresh, output)


def _body(pot: Path) -> list[str]:
    return [line for line in pot.read_text(encoding="utf-8").splitlines() if not line.startswith('"POT-Creation-Date')]


def update() -> None:
    for lang in LANGS:
        if lang == "en":
            continue
        po = LOCALE / LOCALE_DIRS[lang] / "LC_MESSAGES" / f"{DOMAIN}.po"
        if not po.exists():
            pybabel("init", "-i", str(POT), "-d", str(LOCALE), "-D", DOMAIN, "-l", LOCALE_DIRS[lang])
        pybabel("update", "-i", str(POT), "-d", str(LOCALE), "-D", DOMAIN, "-l", LOCALE_DIRS[lang],
                "--no-fuzzy-matching", "--ignore-obsolete", "--no-wrap")


def compile_all() -> None:
    pybabel("compile", "-d", str(LOCALE), "-D", DOMAIN, "--statistics")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m conformance.i18n.update", description=__doc__.split("\n")[0])
    parser.parse_args(argv)
    if not (ROOT / "babel.cfg").is_file():
        print("conformance.i18n.update: run it from a source checkout (babel.cfg not found)", file=sys.stderr)
        return 2
    extract()
    update()
    compile_all()
    return 0


if __name__ == "__main__":
    sys.exit(main())
