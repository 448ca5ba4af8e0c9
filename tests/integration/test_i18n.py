"""``--lang en|zh-CN`` (issue 21): the language comes from the option or the locale, reaches every
report a person reads, and never the values machines read.

The end-to-end runs use ``--cases 'A4-*'`` against the bundled box (a few seconds each).
"""

from __future__ import annotations

import io
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from rich.cells import cell_len
from rich.console import Console

from conformance import i18n
from conformance.commands import COMMANDS, build_parser, main
from conformance.report.html import render_html
from conformance.report.junit import junit_bytes
from conformance.report.summary import overall_line, write_summary
from conformance.report.terminal import print_final_table
from tests.unit.test_report_summary import sample_cases, sample_root_causes, sample_suite

CJK = re.compile(r"[\u4e00-\u9fff]")
#: the commands that take --lang (the registry's flag)
LANG_COMMANDS = tuple(c.name for c in COMMANDS if c.lang)


@pytest.mark.parametrize(("env", "lang"), [
    ({"LANG": "zh_CN.UTF-8"}, "zh-CN"),
    ({"LANG": "zh_TW.UTF-8"}, "zh-CN"),  # the only Chinese catalogue
    ({"LANG": "en_US.UTF-8"}, "en"),
    ({}, "en"),
    ({"LANG": "C.UTF-8", "LC_MESSAGES": "zh_CN.UTF-8"}, "zh-CN"),
    ({"LANG": "zh_CN.UTF-8", "LC_MESSAGES": "de_DE.UTF-8"}, "en"),  # LC_MESSAGES before LANG
    ({"LC_ALL": "zh_CN.UTF-8", "LC_MESSAGES": "en_GB.UTF-8"}, "zh-CN"),  # LC_ALL before both
    ({"LANG": "fr_FR.UTF-8"}, "en"),
])
def test_default_language_follows_the_locale(env, lang):
    assert i18n.default_lang(env) == lang


def test_language_block_restores_the_one_before():
    assert i18n.current() == "en"
    with i18n.language("zh_CN.UTF-8") as chosen:
        assert chosen == i18n.current() == "zh-CN"
        assert i18n.gettext("Acceptance") == "验收"
        with i18n.language("en"):
            assert i18n.gettext("Acceptance") == "Acceptance"
        assert i18n.current() == "zh-CN"
    assert i18n.current() == "en"
    with pytest.raises(ValueError, match="not one of en, zh-CN"):
        i18n.normalise("klingon")


def test_verdicts_keep_their_token_with_the_word_beside_it():
    assert i18n.beside("FAIL") == "FAIL"
    assert i18n.level_name("MUST/SHOULD") == "MUST/SHOULD"
    with i18n.language("zh-CN"):
        assert i18n.beside("FAIL") == "FAIL 不通过"
        assert i18n.beside("NON-STRICT") == "NON-STRICT 非严格"
        assert i18n.level_name("MUST/SHOULD") == "应 (MUST)/宜 (SHOULD)"


def test_every_reader_facing_command_takes_lang(monkeypatch):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in LANG_COMMANDS:
        option = next(a for a in sub.choices[name]._actions if a.dest == "lang")
        assert option.option_strings == ["--lang"] and option.default is None
    assert set(LANG_COMMANDS) >= {"run", "certify-robot", "analyze", "fuzz", "diff", "clauses"}


def test_help_is_translated_and_a_bad_language_is_a_usage_error(capsys, monkeypatch):
    monkeypatch.setenv("LC_ALL", "C")
    monkeypatch.setenv("COLUMNS", "80")
    with pytest.raises(SystemExit) as done:
        main(["run", "--lang", "zh-CN", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "对 AI Box 运行一致性测试" in out and "报告和终端输出的语言" in out
    assert max(cell_len(line) for line in out.splitlines()) <= 80  # wrapped by columns, not characters
    assert i18n.current() == "en"  # main() leaves the process's language as it found it
    with pytest.raises(SystemExit) as done:
        main(["clauses", "--lang", "tlh"])
    assert done.value.code == 2
    err = capsys.readouterr().err
    assert "--lang" in err and "Traceback" not in err


def test_clauses_in_chinese(capsys):
    assert main(["clauses", "--lang", "zh-CN", "--brief", "F1"]) == 0
    assert capsys.readouterr().out.strip() == "F1  MUST        起始字为 FE FE"
    assert main(["clauses", "--lang", "zh-CN", "A4"]) == 0
    out = capsys.readouterr().out
    assert "机器人发送无动作请求，服务器仍然响应" in out  # the source document, quoted as written
    assert all(cell_len(line) <= 88 for line in out.splitlines() if not line.startswith(("    source:", "      ")))


def test_the_report_in_chinese_with_the_verdict_tokens_kept():
    cases, rcs = sample_root_causes()
    with i18n.language("zh-CN"):
        html = render_html(sample_suite(), cases, root_causes=rcs)
    assert '<html lang="zh-CN">' in html
    for words in ("iSight 协议一致性测试报告", "验收", "测试人（姓名、单位）", "签字", "根本原因（1）", "按条款和要求等级的判定",
                  "期望", "实际", "起始字为 FE FE", "第 \" counter(page) \" 页，共 \" counter(pages) \" 页"):
        assert words in html, words
    assert "不符合：13 项 FAIL（不通过）" in html
    assert re.search(r'<span class="badge">FAIL 不通过</span><span class="cid">F1-01</span>', html)
    assert 'data-verdict="FAIL"' in html  # the filter and CI-facing values keep the token
    english = render_html(sample_suite(), cases, root_causes=rcs)
    assert '<html lang="en">' in english and "Acceptance" in english and not CJK.search(english)


def test_terminal_summary_in_chinese_fits_80_columns():
    cases, rcs = sample_root_causes()
    console = Console(file=io.StringIO(), width=80)
    with i18n.language("zh-CN"):
        print_final_table(sample_suite(), cases, console, reports={"HTML report": "r/report.html"}, root_causes=rcs)
    lines = console.file.getvalue().splitlines()
    assert any("根本原因（1），按修复顺序排列：" in line for line in lines)
    assert any(line.startswith("不符合：13 项 FAIL（不通过）") for line in lines)
    assert any(line.startswith("HTML 报告: r/report.html") for line in lines)
    wide = [line for line in lines if cell_len(line) > len(line)]
    assert wide  # double-width characters: rich measures them as two columns each
    for line in lines:
        assert cell_len(line) <= 80, line


def test_junit_messages_in_chinese_machine_values_in_english():
    cases, rcs = sample_root_causes()
    with i18n.language("zh-CN"):
        root = ET.fromstring(junit_bytes(sample_suite(), cases, rcs))
    props = {p.get("name"): p.get("value") for p in root.iter("property")}
    assert props["lang"] == "zh-CN"
    assert props["overall"] == overall_line(cases, sample_suite())  # English, whatever the language
    failures = list(root.iter("failure"))
    assert {f.get("type") for f in failures} == {"FAIL"}
    assert any("根本原因：RC1" in f.text for f in failures) and any("期望: " in f.text for f in failures)
    assert any(f.text.startswith("FAIL: ") and "\n条款 " in f.text for f in failures)
    assert "违反了“宜”(SHOULD) 要求" in "".join(el.text or "" for el in root.iter("system-out"))


def test_summary_json_records_the_language_and_stays_english(tmp_path):
    with i18n.language("zh-CN"):
        doc = write_summary(tmp_path / "summary.json", sample_suite(), sample_cases())
    assert doc["suite"]["lang"] == "zh-CN"
    assert {c["verdict"] for c in doc["cases"]} <= {"PASS", "FAIL", "ERROR", "NON-STRICT", "INFORMATIONAL",
                                                    "INCONCLUSIVE", "SKIP"}
    assert list(doc["totals"]) == ["FAIL", "ERROR", "NON-STRICT", "INCONCLUSIVE", "INFORMATIONAL", "SKIP", "PASS"]
    assert json.loads((tmp_path / "summary.json").read_text(encoding="utf-8")) == doc


@pytest.mark.parametrize(("argv", "env", "chinese"), [
    (["--lang", "zh-CN"], {"LC_ALL": "C"}, True),  # the option wins over the locale
    ([], {"LANG": "zh_CN.UTF-8"}, True),  # no option: the locale
    (["--lang", "en"], {"LANG": "zh_CN.UTF-8"}, False),
])
def test_run_writes_its_reports_in_the_chosen_language(tmp_path: Path, monkeypatch, capsys, argv, env, chinese):
    for name in ("LC_ALL", "LC_MESSAGES", "LANG"):
        monkeypatch.delenv(name, raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--cases", "A4-*", "--quiet", "--report-dir", "r", "--pcap-dir", "p", *argv]) == 0
    out = capsys.readouterr().out
    html = (tmp_path / "r" / "report.html").read_text(encoding="utf-8")
    summary = json.loads((tmp_path / "r" / "summary.json").read_text(encoding="utf-8"))
    assert summary["suite"]["lang"] == ("zh-CN" if chinese else "en")
    assert ("验收" in html) is chinese and ("Acceptance" in html) is not chinese
    assert ("符合（无 FAIL/ERROR）" in out) is chinese and ("CONFORMS (no FAIL/ERROR)" in out) is not chinese
    assert i18n.current() == "en"


def test_the_fleet_page_in_chinese_keeps_the_statuses_machines_read(tmp_path: Path):
    from conformance.fleet.fleet_page import render_fleet_html
    from tests.unit.test_fleet_page import doc_for

    with i18n.language("zh-CN"):
        doc = doc_for(tmp_path)
        html = render_fleet_html(doc)
    assert doc["lang"] == "zh-CN" and doc["overall"].startswith("未完成：测试被中止")
    assert [b["status"] for b in doc["boxes"]] == ["conforms", "fails", "error", "not run"]  # machine values
    assert '<html lang="zh-CN">' in html and "iSight 一致性测试：批量测试" in html
    assert '<span class="badge ok">符合</span>' in html and 'data-status="conforms"' in html
    assert "未运行：批量测试在该 AI Box 开始前被中止" in html


def test_diff_in_chinese(tmp_path: Path, capsys):
    from dataclasses import replace

    from conformance.model.verdicts import Verdict

    cases = sample_cases()
    write_summary(tmp_path / "old.json", sample_suite(), cases)
    worse = [replace(c, verdict=Verdict.FAIL) if c.verdict is Verdict.PASS else c for c in cases]
    write_summary(tmp_path / "new.json", sample_suite(), worse)
    assert main(["diff", "--lang", "zh-CN", str(tmp_path / "old.json"), str(tmp_path / "new.json")]) == 1
    out = capsys.readouterr().out
    assert "OLD 结果：不符合：" in out and "变差 (2):" in out and "PASS → FAIL" in out
    assert out.rstrip().splitlines()[-1].startswith("变差：2 个变差，0 个变好")


def test_wrapped_chinese_keeps_its_punctuation_with_its_neighbour():
    text = ("[R2] 使失效的 AI Box 恢复运行的 shell 命令（例如 'systemctl restart aibox'）：有了它，AI Box 的失效会被"
            "确认，并缩减为导致失效的最短序列（例如【一二三】）")
    for width in range(20, 80):
        lines = i18n.wrap_cells(text, width)
        assert "".join(lines).replace(" ", "") == text.replace(" ", "")  # nothing lost, nothing added
        assert all(i18n.cells(line) <= width for line in lines), width
        assert not any(line[0] in "，。、；：）】" for line in lines), (width, lines)  # no line opens with a closing mark
        assert not any(line[-1] in "（【" for line in lines), (width, lines)  # nor ends with an opening one


def test_monitor_help_and_status_line_in_chinese(capsys, monkeypatch):
    from conformance.analyze.analysis_context import AnalyzeConfig
    from conformance.monitor.hub import Hub, MonitorSettings
    from conformance.monitor.view import View

    monkeypatch.setenv("COLUMNS", "80")
    with pytest.raises(SystemExit) as done:
        main(["monitor", "--lang", "zh-CN", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "等待机器人连接" in out and "故障注入" in out and "机器人连接的地址" in out
    assert max(cell_len(line) for line in out.splitlines()) <= 80
    hub = Hub(MonitorSettings(("127.0.0.1", 1), ("127.0.0.1", 9004), AnalyzeConfig(ports=(9004,)), None))
    view = View(io.StringIO(), tty=False)
    view.counts.update(hub)
    english = view.status(hub)
    with i18n.language("zh-CN"):
        chinese = view.status(hub)
    assert " status: 0 open / 0 connection(s), 0 session(s) done, frames robot→box 0 box→robot 0, " in english
    assert " 状态：0 个已打开 / 共 0 个连接，已完成 0 个会话，" in chinese and "ms；" in chinese
