"""The message catalogues are complete and current (issue 21).

* every string the code and the templates mark for translation (extracted here with Babel, as
  ``python -m conformance.i18n.update`` does) is in each ``.po``; a string the catalogue lacks fails with its text;
* every entry has its translation (not empty, not fuzzy), with the same placeholders as its msgid;
* the committed ``.mo`` is the compiled ``.po`` (run the update command after editing a ``.po``);
* the templates show no English text outside ``{% trans %}`` / ``_()``;
* every clause has its Chinese title and text, quoting the source document where it speaks.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

babel = pytest.importorskip("babel", reason="Babel manages the catalogues: pip install -e '.[test]'")

from babel.messages.mofile import read_mo  # noqa: E402
from babel.messages.pofile import read_po  # noqa: E402

from conformance import i18n  # noqa: E402
from conformance.i18n import update  # noqa: E402
from conformance.protocol.clauses import all_clauses, families  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CATALOGUES = {lang: update.LOCALE / i18n.LOCALE_DIRS[lang] / "LC_MESSAGES" for lang in i18n.LANGS if lang != "en"}
CJK = re.compile(r"[\u4e00-\u9fff]")
SAME_IN_CHINESE = {"JUnit", "Box", "Boxes"}  # the glossary keeps "AI Box"; JUnit is a name
PLACEHOLDER = re.compile(r"%\((\w+)\)s|\{(\w+)\}")


def _po(lang: str):
    with open(CATALOGUES[lang] / f"{i18n.DOMAIN}.po", "rb") as fh:
        return read_po(fh)


def _messages(catalog) -> dict[object, object]:
    return {m.id: m.string for m in catalog if m.id}


@pytest.fixture(scope="module")
def extracted(tmp_path_factory) -> set[object]:
    pot = tmp_path_factory.mktemp("pot") / "isight.pot"
    update.extract(pot)
    with open(pot, "rb") as fh:
        return {m.id for m in read_po(fh) if m.id}


def test_extraction_finds_the_report_terminal_and_help_strings(extracted):
    # the extraction itself works (a broken babel.cfg would make every later comparison vacuous)
    for needle in ("Acceptance", "Totals:", "Verdict by clause and level", "DOES NOT CONFORM: {fail} FAIL, {error} ERROR",
                   "The box writes error codes with their bytes swapped (little-endian): 1001 goes out as 01 10"):
        assert needle in extracted
    assert len(extracted) > 300


@pytest.mark.parametrize("lang", sorted(CATALOGUES))
def test_every_marked_string_is_in_the_catalogue(extracted, lang):
    have = set(_messages(_po(lang)))
    missing = sorted(map(str, extracted - have))
    assert not missing, (f"{len(missing)} string(s) not in the {lang} catalogue; run `python -m conformance.i18n.update` "
                         f"and translate them: {missing[:10]}")
    stale = sorted(map(str, have - extracted))
    assert not stale, f"{lang} catalogue holds strings the code no longer has (run the update command): {stale[:10]}"


@pytest.mark.parametrize("lang", sorted(CATALOGUES))
def test_every_entry_has_its_translation_with_the_same_placeholders(lang):
    catalog = _po(lang)
    assert not catalog.fuzzy, "the catalogue header is marked fuzzy: pybabel compile would skip it"
    problems = []
    for msg in catalog:
        if not msg.id:
            continue
        ids = msg.id if isinstance(msg.id, tuple) else (msg.id,)
        strings = msg.string if isinstance(msg.string, tuple) else (msg.string,)
        if "fuzzy" in msg.flags or not all(strings):
            problems.append(f"untranslated: {ids[0]!r}")
            continue
        wanted = {a or b for a, b in PLACEHOLDER.findall(ids[-1])}
        for s in strings:
            if {a or b for a, b in PLACEHOLDER.findall(s)} != wanted:
                problems.append(f"placeholders differ: {ids[0]!r} -> {s!r}")
        if lang == "zh-CN" and not CJK.search("".join(strings)) and ids[0] not in SAME_IN_CHINESE:
            problems.append(f"not Chinese: {ids[0]!r} -> {strings[0]!r}")
    assert not problems, "\n".join(problems[:20])


@pytest.mark.parametrize("lang", sorted(CATALOGUES))
def test_the_committed_mo_is_the_compiled_po(lang):
    def plain(value: object) -> object:
        return tuple(value) if isinstance(value, (list, tuple)) else value

    with open(CATALOGUES[lang] / f"{i18n.DOMAIN}.mo", "rb") as fh:
        compiled = {plain(m.id): plain(m.string) for m in read_mo(fh) if m.id}
    source = {plain(k): plain(v) for k, v in _messages(_po(lang)).items()}
    assert compiled == source, "isight.mo is out of date: run `python -m conformance.i18n.update`"


def _visible_text(template: str) -> str:
    """The template's text a reader sees that is not translated: style, script, translated blocks,
    expressions, statements, comments, tags and entities removed."""
    text = re.sub(r"<style>.*?</style>|<script>.*?</script>", " ", template, flags=re.S)
    text = re.sub(r"{% trans[^%]*%}.*?{% endtrans %}", " ", text, flags=re.S)
    text = re.sub(r"{{.*?}}|{%.*?%}|{#.*?#}", " ", text, flags=re.S)
    text = re.sub(r"<[^>]*>|&\w+;", " ", text)
    return text


@pytest.mark.parametrize("template", sorted((ROOT / "conformance").glob("*/templates/*.j2")), ids=lambda p: p.name)
def test_templates_show_no_untranslated_words(template):
    words = re.findall(r"[A-Za-z][A-Za-z'-]+", _visible_text(template.read_text(encoding="utf-8")))
    allowed = {"isight-conformance", "pcap", "hex", "report", "html", "summary", "json", "junit", "xml", "pcaps", "run", "log"}  # file names
    stray = [w for w in words if w.lower() not in allowed]
    assert not stray, f"{template.name}: text outside {{% trans %}} or _(): {stray[:20]}"


def test_every_clause_has_its_chinese_title_and_text_quoting_the_source():
    for clause in all_clauses().values():
        title, text = clause.words("zh-CN")
        assert (title, text) != (clause.title, clause.text), f"{clause.id} has no Chinese text"
        assert CJK.search(title) and CJK.search(text), clause.id
        # where the source document speaks (a Chinese quotation in 'source'), the text quotes it as written
        quotes = [q for q in re.findall(r"“([^”]*)”", clause.source) if CJK.search(q)]
        pieces = [p.strip(" …") for q in quotes for p in q.split("…") if CJK.search(p)]
        if pieces:
            assert any(p in text for p in pieces), f"{clause.id}: none of the source's words {pieces[:2]} quoted"
    assert all(CJK.search(name) for name in families("zh-CN").values())
    assert families("en") == families()
