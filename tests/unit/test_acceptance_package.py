"""The acceptance package's pure parts: the manifest and its check, --dut, the report's first page."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conformance.acceptance import manifest
from conformance.acceptance.dut import parse_dut, read_dut_file, resolve_dut
from conformance.acceptance.record import new
from conformance.acceptance.tester import git_commit, identity
from conformance.report import packaged, write_reports
from conformance.report.summary import write_summary
from tests.unit.test_report_summary import sample_cases, sample_suite


def _package(root: Path) -> Path:
    (root / "pcaps").mkdir(parents=True)
    (root / "pcaps" / "F1-01.pcapng").write_bytes(bytes(range(256)))
    (root / "summary.json").write_text('{"cases": []}\n')
    (root / "report.html").write_text('<p>x</p><code class="manifest-sha256">' + "0" * 64 + "</code>\n")
    return root


def test_a_sealed_package_checks_ok_and_its_report_shows_the_manifest_hash(tmp_path: Path) -> None:
    root = _package(tmp_path / "acc")
    digest = manifest.seal(root, "run-1")
    doc = json.loads((root / "manifest.json").read_text())
    assert [f["path"] for f in doc["files"]] == ["pcaps/F1-01.pcapng", "report.html", "summary.json"]
    assert doc["files"][0]["size"] == 256 and doc["run_id"] == "run-1"
    assert digest in (root / "report.html").read_text()
    found = manifest.check(root)
    assert found.ok and found.files == 3 and found.manifest_sha256 == digest


def test_one_flipped_byte_an_added_and_a_removed_file_are_each_named(tmp_path: Path) -> None:
    root = _package(tmp_path / "acc")
    manifest.seal(root)
    pcap = root / "pcaps" / "F1-01.pcapng"
    data = bytearray(pcap.read_bytes())
    data[100] ^= 0x01
    pcap.write_bytes(bytes(data))
    (root / "pcaps" / "extra.pcapng").write_bytes(b"x")
    (root / "summary.json").unlink()
    found = manifest.check(root)
    assert not found.ok
    assert {(p.kind, p.path) for p in found.problems} == {
        ("changed", "pcaps/F1-01.pcapng"), ("added", "pcaps/extra.pcapng"), ("removed", "summary.json")}


def test_an_edited_report_or_a_replaced_manifest_hash_is_caught(tmp_path: Path) -> None:
    root = _package(tmp_path / "acc")
    manifest.seal(root)
    report = root / "report.html"
    report.write_text(report.read_text().replace("<p>x</p>", "<p>y</p>"))
    assert [(p.kind, p.path) for p in manifest.check(root).problems] == [("changed", "report.html")]
    root2 = _package(tmp_path / "acc2")
    manifest.seal(root2)
    text = (root2 / "report.html").read_text()
    shown = text.split('manifest-sha256">')[1][:64]
    (root2 / "report.html").write_text(text.replace(shown, "f" * 64))
    assert [(p.kind, p.path) for p in manifest.check(root2).problems] == [("report-field", "report.html")]


def test_signatures_are_outside_the_manifest_and_a_missing_manifest_is_one_line(tmp_path: Path) -> None:
    root = _package(tmp_path / "acc")
    manifest.seal(root)
    (root / "signatures").mkdir()
    (root / "signatures" / "alice.sig").write_text("sig")
    assert manifest.check(root).ok
    with pytest.raises(ValueError, match="cannot read the manifest"):
        manifest.check(tmp_path)
    with pytest.raises(ValueError, match="no such directory"):
        manifest.check(tmp_path / "nope")
    (root / "manifest.json").write_text("{}")
    with pytest.raises(ValueError, match="not an isight-conformance manifest"):
        manifest.check(root)


def test_dut_from_the_line_and_from_a_file(tmp_path: Path) -> None:
    assert parse_dut("vendor=Acme,model=VB-200,firmware=2.1.4,serial=SN42,site=Plant 3, line 2") == {
        "vendor": "Acme", "model": "VB-200", "firmware": "2.1.4", "serial": "SN42", "site": "Plant 3, line 2"}
    file = tmp_path / "dut.toml"
    file.write_text('[dut]\nvendor = "Acme"\nserial = "SN1"\noperator = "A. Tester"\n')
    assert read_dut_file(file) == {"vendor": "Acme", "serial": "SN1", "operator": "A. Tester"}
    assert resolve_dut("serial=SN2", str(file)) == {"vendor": "Acme", "serial": "SN2", "operator": "A. Tester"}
    for bad, words in (("colour=red", "unknown key"), ("vendor", "expected key=value"),
                       ("vendor=a,vendor=b", "given twice"), ("vendor=", "printable")):
        with pytest.raises(ValueError, match=words):
            parse_dut(bad)
    file.write_text("vendor = [")
    with pytest.raises(ValueError, match="not TOML"):
        read_dut_file(file)


def test_the_tester_names_the_suite_its_commit_and_libraries() -> None:
    me = identity()
    assert me["suite"] == "isight-conformance" and me["clause_registry_version"]
    assert set(me["libraries"]) == {"hypothesis", "scapy", "crcmod-plus", "pytest", "Jinja2"}
    assert me["libraries"]["pytest"] == pytest.__version__
    assert len(me["protocol_md_sha256"]) == 64  # the checkout's docs/PROTOCOL.md
    commit = git_commit()
    assert commit == "" or (len(commit) == 40 and int(commit, 16) >= 0)


def test_pcaps_inside_the_package_are_named_relative_to_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    cases = sample_cases()
    cases[0].pcap = "acc/pcaps/F1-01.pcapng"
    cases[1].pcap = str(tmp_path / "elsewhere" / "A3-02.pcapng")
    out = packaged(cases, Path("acc"))
    assert out[0].pcap == "pcaps/F1-01.pcapng" and out[1].pcap == str(tmp_path / "elsewhere" / "A3-02.pcapng")
    assert cases[0].pcap == "acc/pcaps/F1-01.pcapng"  # the caller's results are left as they were


def test_summary_and_report_carry_the_acceptance(tmp_path: Path) -> None:
    acc = new({"vendor": "Acme", "model": "VB-200"})
    doc = write_summary(tmp_path / "summary.json", sample_suite(), sample_cases(), acceptance=acc.to_dict())
    assert doc["acceptance"]["run_id"] == acc.run_id and doc["acceptance"]["dut"]["vendor"] == "Acme"
    assert doc["acceptance"]["table_source"] == "inferred"
    write_reports(tmp_path / "pkg", sample_suite(), sample_cases(), acceptance=acc.to_dict())
    html = (tmp_path / "pkg" / "report.html").read_text()
    assert html.count(acc.run_id) >= 3  # the header, the test system table and every printed page's footer
    assert f'"iSight conformance report · run {acc.run_id}"' in html
    assert "apply only to the item tested" in html and "VB-200" in html
    assert "Serial number" in html and "Firmware" in html  # named as not declared
    assert '<code class="manifest-sha256">' + "0" * 64 in html
    junit = (tmp_path / "pkg" / "junit.xml").read_text()
    assert f'<property name="run_id" value="{acc.run_id}" />' in junit
    assert '<property name="dut.model" value="VB-200" />' in junit
    plain = tmp_path / "plain"
    write_reports(plain, sample_suite(), sample_cases())
    assert "manifest-sha256" not in (plain / "report.html").read_text()
    assert "acceptance" not in json.loads((plain / "summary.json").read_text())


def test_analyze_copies_its_capture_into_the_package_and_verify_agrees(tmp_path: Path, capsys) -> None:
    from conformance.commands import main
    from tests.analyze_util import Capture, canonical

    cap = Capture()
    canonical(cap)
    capture = cap.write(tmp_path / "line.pcapng")
    pkg = tmp_path / "pkg"
    assert main(["analyze", str(capture), "--report-dir", str(pkg), "--jitter-tolerance", "300",
                 "--dut", "vendor=Acme,serial=SN9"]) == 0
    assert (pkg / "capture" / "line.pcapng").read_bytes() == capture.read_bytes()
    doc = json.loads((pkg / "summary.json").read_text())
    assert {c["pcap"] for c in doc["cases"] if c["pcap"]} == {"capture/line.pcapng"}
    assert doc["acceptance"]["dut"] == {"vendor": "Acme", "serial": "SN9"}
    capsys.readouterr()
    assert main(["verify", str(pkg)]) == 0
    assert capsys.readouterr().out.startswith("OK: ")
    (pkg / "capture" / "line.pcapng").write_bytes(capture.read_bytes() + b"\0")
    assert main(["verify", str(pkg)]) == 1
    assert "CHANGED: capture/line.pcapng" in capsys.readouterr().out


def test_sealing_again_keeps_the_old_signatures_as_superseded_evidence(tmp_path: Path) -> None:
    root = _package(tmp_path / "acc")
    first = manifest.seal(root)
    (root / "signatures").mkdir()
    (root / "signatures" / "alice.sig").write_text("old signature")
    assert manifest.seal(root) == first  # nothing changed: the signatures still sign this manifest
    assert (root / "signatures" / "alice.sig").is_file()
    (root / "summary.json").write_text('{"cases": [1]}\n')  # a second run into the same directory
    second = manifest.seal(root)
    kept = root / f"signatures-superseded-{first[:16]}" / "alice.sig"
    assert second != first and kept.read_text() == "old signature" and not (root / "signatures").exists()
    assert f"signatures-superseded-{first[:16]}/alice.sig" in (root / "manifest.json").read_text()
    assert manifest.check(root).ok


def test_pcaps_outside_the_package_are_named_on_the_page(tmp_path: Path) -> None:
    acc = new().to_dict()
    cases = sample_cases()
    cases[0].pcap = str(tmp_path / "pcaps" / "20240601-101500" / "F1-01.pcapng")
    write_reports(tmp_path / "pkg", sample_suite(), cases, acceptance=acc)
    doc = json.loads((tmp_path / "pkg" / "summary.json").read_text())
    assert doc["acceptance"]["outside_package"] == [str(tmp_path / "pcaps" / "20240601-101500")]
    assert "lie outside the package" in (tmp_path / "pkg" / "report.html").read_text()
    inside = sample_cases()
    inside[0].pcap = str(tmp_path / "inside" / "pcaps" / "F1-01.pcapng")
    write_reports(tmp_path / "inside", sample_suite(), inside, acceptance=acc)
    assert "lie outside the package" not in (tmp_path / "inside" / "report.html").read_text()
