"""fleet.html (conformance/fleet/fleet_page.py): one row per box, each linking its report; nothing a box sent
becomes markup; no external reference."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

from conformance.fleet.fleet_page import render_fleet_html, write_fleet_html
from conformance.fleet.fleet_results import fleet_document
from conformance.model.verdicts import RootCause, Verdict
from tests.fleet_util import box_run, case


class Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.rows: list[dict[str, str]] = []
        self.links: list[str] = []
        self.external: list[str] = []
        self.scripts = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "tr" and "box" in (a.get("class") or "").split():
            self.rows.append({k: v or "" for k, v in a.items()})
        if tag == "a" and a.get("href"):
            self.links.append(a["href"] or "")
        if tag in ("script", "img", "link", "iframe"):
            self.scripts += 1
        for key in ("src", "href"):
            value = a.get(key) or ""
            if re.match(r"^[a-z]+:", value):
                self.external.append(value)


def doc_for(tmp_path: Path) -> dict:
    evil = RootCause("RC1", ("A5",), "<script>alert('x')</script> answers unknown actions", "fe fe", ["A5-01"])
    runs = [
        box_run(tmp_path, "cell-1", cases=[case("A4-01", Verdict.PASS)]),
        box_run(tmp_path, "cell-2", exit_code=1, root_causes=(evil,), cases=[case("A5-01", Verdict.FAIL, "RC1")]),
        box_run(tmp_path, "cell-3", exit_code=2, log="isight-conformance run: target <b>x</b> unreachable\n",
                target="10.0.0.7:9004"),
        box_run(tmp_path, "cell-4", status="not run", exit_code=None),
    ]
    return fleet_document(runs, tmp_path, fleet_file=Path("plant.toml"), jobs=2, started="2024-06-01T10:15:00+00:00",
                          duration_s=75.0, command="isight-conformance run --targets plant.toml --jobs 2",
                          stopped="stopped by SIGTERM")


def test_one_row_per_box_in_file_order_with_its_status(tmp_path: Path) -> None:
    page = Page()
    page.feed(render_fleet_html(doc_for(tmp_path)))
    assert [r["data-status"] for r in page.rows] == ["conforms", "fails", "error", "not run"]
    assert [r["id"] for r in page.rows] == ["box-1", "box-2", "box-3", "box-4"]


def test_each_report_is_linked_relative_to_the_fleet_page(tmp_path: Path) -> None:
    path = write_fleet_html(tmp_path / "fleet.html", doc_for(tmp_path))
    page = Page()
    page.feed(path.read_text(encoding="utf-8"))
    reports = [link for link in page.links if link.endswith("report.html")]
    assert reports == ["cell-1/report.html", "cell-2/report.html"]
    for link in page.links:  # every link resolves to a file or directory the fleet wrote
        assert (tmp_path / link.rstrip("/")).exists(), link
    assert "cell-3/run.log" in page.links  # the box that could not run: its log
    assert page.external == [] and page.scripts == 0  # self-contained


def test_the_overall_line_root_causes_and_errors_are_shown_escaped(tmp_path: Path) -> None:
    html = render_fleet_html(doc_for(tmp_path))
    assert "INCOMPLETE: the run was stopped; 3 of 4 boxes finished, 1 of them passed" in html
    assert "stopped by SIGTERM" in html
    assert "<script>" not in html and "&lt;script&gt;alert(" in html
    assert "answers unknown actions" in html and "RC1" in html
    assert "<b>x</b>" not in html and "target &lt;b&gt;x&lt;/b&gt; unreachable" in html
    assert "1 min 15 s (2 at a time)" in html
