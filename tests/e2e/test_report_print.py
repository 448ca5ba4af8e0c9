"""report.html on paper: printed to A4 with headless Chromium it stays an acceptance
document (issue 13): at most 15 pages for a conforming box, 40 for a broken one.

The runs are shaped like real ones (``tests/reportruns.py``); the figures for a real
``isight-conformance run`` are printed by ``benchmarks/bench_report_print.py``.
"""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from conformance import i18n
from conformance.report.html import write_html
from tests.reportruns import chromium, conforming_run, pdf_pages, print_to_pdf, systematic_defect, without_root_causes
from tests.unit.test_report_summary import sample_root_causes, sample_suite

pytestmark = [
    pytest.mark.skipif(chromium() is None, reason="headless Chromium is not installed (apt-get install chromium)"),
    pytest.mark.timeout(600),
]

CONFORMING_PAGES, BROKEN_PAGES = 15, 40


#: fonts with the CJK ideographs (fonts-noto-cjk on Debian, and the other common ones)
CJK_FONT = re.compile(rb"/FontName\s*/[A-Z]{6}\+[^\s/]*(?:CJK|SourceHan|WenQuanYi|DroidSansFallback|UKai|UMing)")


def _pages(tmp_path, name, cases, root_causes=(), lang="en") -> int:
    html = tmp_path / f"{name}.html"
    with i18n.language(lang):
        write_html(html, sample_suite(), cases, root_causes=root_causes)
    pages = print_to_pdf(html, tmp_path / f"{name}.pdf")
    print(f"\n{name} ({lang}): {pages} A4 pages")
    return pages


def _cjk_glyphs_embedded(pdf) -> bool:
    return CJK_FONT.search(pdf.read_bytes()) is not None


def test_a_conforming_box_prints_to_at_most_15_pages(tmp_path):
    cases = conforming_run()
    assert len(cases) == 275 and sum(len(c.wire) for c in cases) > 10_000
    pages = _pages(tmp_path, "conforming", cases)
    assert 2 <= pages <= CONFORMING_PAGES


def test_a_systematic_defect_prints_to_at_most_40_pages(tmp_path):
    cases, rcs = systematic_defect(conforming_run())
    assert sum(c.verdict.value == "FAIL" for c in cases) == 150 and len(rcs[0].cases) == 220
    assert _pages(tmp_path, "systematic", cases, rcs) <= BROKEN_PAGES
    # a suite that names no root cause: the repeated findings still print once each
    assert _pages(tmp_path, "systematic-no-root-cause", without_root_causes(cases)) <= BROKEN_PAGES


def test_the_chinese_report_prints_within_the_english_budgets(tmp_path):
    """--lang zh-CN: the same runs, in Chinese, within the same page budgets."""
    cases = conforming_run()
    pages = _pages(tmp_path, "conforming-zh", cases, lang="zh-CN")
    assert 2 <= pages <= CONFORMING_PAGES
    html = (tmp_path / "conforming-zh.html").read_text(encoding="utf-8")
    assert '<html lang="zh-CN">' in html and "验收" in html and "签字" in html
    broken, rcs = systematic_defect(cases)
    assert _pages(tmp_path, "systematic-zh", broken, rcs, lang="zh-CN") <= BROKEN_PAGES
    assert _pages(tmp_path, "systematic-no-root-cause-zh", without_root_causes(broken), lang="zh-CN") <= BROKEN_PAGES


def cjk_font_installed() -> bool:
    fc_list = shutil.which("fc-list")
    if fc_list is None:
        return False
    done = subprocess.run([fc_list, ":lang=zh", "family"], capture_output=True, text=True, timeout=30)
    return bool(done.stdout.strip())


@pytest.mark.skipif(not cjk_font_installed(), reason="no CJK font installed (apt-get install fonts-noto-cjk)")
def test_the_chinese_report_prints_cjk_glyphs(tmp_path):
    """The PDF embeds a CJK font, so the ideographs print as glyphs, not empty boxes (.ci/run installs
    fonts-noto-cjk); the English report needs none."""
    cases, rcs = sample_root_causes()
    _pages(tmp_path, "sample-zh", cases, rcs, lang="zh-CN")
    assert _cjk_glyphs_embedded(tmp_path / "sample-zh.pdf")
    _pages(tmp_path, "sample-en", cases, rcs)
    assert not _cjk_glyphs_embedded(tmp_path / "sample-en.pdf")


def test_pdf_page_counter():
    two = b"%PDF-1.4\n1 0 obj <</Type /Pages /Kids [2 0 R 3 0 R] /Count 2>> endobj\n" \
          b"2 0 obj <</Type /Page /Parent 1 0 R>> endobj\n3 0 obj <</Type/Page/Parent 1 0 R>> endobj\n"
    assert pdf_pages(two) == 2
    compressed = b"%PDF-1.5\n1 0 obj <</Type /Pages /Count 17 /Kids [...]>> endobj\n"
    assert pdf_pages(compressed) == 17
