"""The acceptance package as a receiver handles it (issue 37): moved, zipped, signed with the real
``ssh-keygen``, verified, tampered with; and a vendor's declaration the box contradicts."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from urllib.parse import unquote

import pytest

from tests.impls.box import start_box

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]
SSH_KEYGEN = shutil.which("ssh-keygen")
needs_ssh_keygen = pytest.mark.skipif(SSH_KEYGEN is None, reason="ssh-keygen (OpenSSH) is not installed")
CASES = ["PROFILE-01", "F4-*", "T1-01"]


def cli(cwd: Path, *args: str | Path, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "conformance", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


def run_package(tmp_path: Path, box: str, declared: str, *cases: str) -> tuple[subprocess.CompletedProcess[str], Path]:
    (tmp_path / "declared.toml").write_text(declared)
    (tmp_path / "dut.toml").write_text('vendor = "Acme"\nmodel = "VB-200"\nsite = "Plant 3"\nwitness = "B. Witness"\n')
    with start_box(box) as served:
        args = ["run", "--quiet", "--target", f"127.0.0.1:{served.port}", "--report-dir", "pkg",
                "--dut-file", "dut.toml", "--dut", "firmware=2.1.4,serial=SN0042", "--declared", "declared.toml"]
        for glob in cases or CASES:
            args += ["--cases", glob]
        proc = cli(tmp_path, *args)
    return proc, tmp_path / "pkg"


def keypair(tmp_path: Path, name: str) -> tuple[Path, str]:
    key = tmp_path / "keys" / name
    key.parent.mkdir(exist_ok=True)
    subprocess.run([SSH_KEYGEN, "-q", "-t", "ed25519", "-N", "", "-C", f"{name}@example.com", "-f", str(key)],
                   check=True, timeout=30)
    kind, blob = key.with_suffix(".pub").read_text().split()[:2]
    return key, f"{name}@example.com {kind} {blob}\n"


def local_links(html: str) -> list[str]:
    return [unquote(h) for h in re.findall(r'href="([^"#][^"]*)"', html) if "://" not in h]


@needs_ssh_keygen
def test_a_package_travels_whole_is_signed_and_one_flipped_byte_is_named(tmp_path: Path) -> None:
    proc, pkg = run_package(tmp_path, "trust-header", "first_index = 0\nbyte_order = 'big'\n")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert not (tmp_path / "pcaps").exists() and not (tmp_path / "reports").exists()  # everything is in pkg
    assert {"report.html", "summary.json", "junit.xml", "manifest.json", "pcaps"} <= {p.name for p in pkg.iterdir()}
    doc = json.loads((pkg / "summary.json").read_text())
    acc = doc["acceptance"]
    assert acc["dut"] == {"vendor": "Acme", "model": "VB-200", "firmware": "2.1.4", "serial": "SN0042",
                          "site": "Plant 3", "witness": "B. Witness"}
    assert {r["key"]: r["status"] for r in acc["declared_observed"]} == {"first_index": "confirmed",
                                                                         "byte_order": "confirmed"}
    assert all(c["pcap"].startswith("pcaps/") for c in doc["cases"] if c["pcap"])
    html = (pkg / "report.html").read_text()
    assert acc["run_id"] in html and "SN0042" in html
    links = local_links(html)
    assert links and all(not link.startswith(("/", "..")) for link in links)

    # moved and zipped, the package stays whole
    moved = tmp_path / "elsewhere" / "acceptance"
    moved.parent.mkdir()
    shutil.move(pkg, moved)
    assert all((moved / link).is_file() for link in links)
    shutil.make_archive(str(tmp_path / "acceptance"), "zip", moved)
    with zipfile.ZipFile(tmp_path / "acceptance.zip") as archive:
        archive.extractall(tmp_path / "unzipped")
    for where in (moved, tmp_path / "unzipped"):
        done = cli(tmp_path, "verify", where)
        assert done.returncode == 0 and done.stdout.startswith("OK: "), done.stdout + done.stderr
        assert re.search(r"sha256 ([0-9a-f]{64})", done.stdout)[1] in html  # the hash printed on the page

    # two signers, each adds one signature; the receiver checks both
    vendor, vendor_line = keypair(tmp_path, "vendor")
    witness, witness_line = keypair(tmp_path, "witness")
    assert cli(tmp_path, "sign", moved, "--key", vendor, "--role", "vendor").returncode == 0
    assert cli(tmp_path, "sign", moved, "--key", witness, "--signer", "witness@example.com").returncode == 0
    allowed = tmp_path / "allowed_signers"
    allowed.write_text(vendor_line + witness_line)
    done = cli(tmp_path, "verify", moved, "--allowed-signers", allowed)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count("GOOD SIGNATURE") == 2 and "vendor@example.com (vendor)" in done.stdout
    only_witness = tmp_path / "only_witness"
    only_witness.write_text(witness_line)
    done = cli(tmp_path, "verify", moved, "--allowed-signers", only_witness)
    assert done.returncode == 1 and "BAD SIGNATURE: vendor@example.com" in done.stdout

    # one flipped byte in one pcap: verify fails and names that pcap (and sign refuses the package)
    pcap = moved / "pcaps" / "PROFILE-01.pcapng"
    data = bytearray(pcap.read_bytes())
    data[len(data) // 2] ^= 0x01
    pcap.write_bytes(bytes(data))
    done = cli(tmp_path, "verify", moved, "--allowed-signers", allowed)
    assert done.returncode == 1
    assert [line.split(" (")[0] for line in done.stdout.splitlines() if line.startswith("CHANGED")] == [
        "CHANGED: pcaps/PROFILE-01.pcapng"]
    assert "NOT OK: 1 file problem(s)" in done.stdout
    refused = cli(tmp_path, "sign", moved, "--key", vendor)
    assert refused.returncode == 2 and "does not match its manifest" in refused.stderr


def test_a_declaration_the_box_contradicts_is_a_finding_with_its_clause_bytes_and_pcap(tmp_path: Path) -> None:
    """nan-1001 expects the first block at index 0 and has no extension E; its vendor declares otherwise."""
    proc, pkg = run_package(tmp_path, "nan-1001", "first_index = 1\nextension_e = true\n", "PROFILE-01", "E2-01")
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    doc = json.loads((pkg / "summary.json").read_text())
    rows = {r["key"]: r for r in doc["acceptance"]["declared_observed"]}
    assert rows["first_index"]["status"] == "contradicted" and rows["first_index"]["observed"] == "0"
    assert rows["extension_e"]["status"] == "contradicted" and rows["extension_e"]["observed"] == "false"
    first = rows["first_index"]
    assert first["case"] == "PROFILE-01" and first["pcap"] == "pcaps/PROFILE-01.pcapng" and "fe fe" in first["bytes"]
    assert (pkg / first["pcap"]).is_file()
    decl = {c["id"]: c for c in doc["cases"] if c["id"].startswith("DECL-")}
    assert set(decl) == {"DECL-first_index", "DECL-extension_e"}
    assert decl["DECL-first_index"]["verdict"] == "FAIL" and decl["DECL-first_index"]["judged"] == ["B3"]
    assert doc["suite"]["profile"]["first_index"] == 1  # judged under the declared profile
    assert (pkg / "declared.toml").read_text() == (tmp_path / "declared.toml").read_text()  # the vendor's own words
    assert doc["acceptance"]["declaration"]["file"] == "declared.toml"
    html = (pkg / "report.html").read_text()
    assert "DOES NOT CONFORM" in html and "contradicted" in html and 'href="pcaps/PROFILE-01.pcapng"' in html
    assert cli(tmp_path, "verify", pkg).returncode == 0


def test_bad_acceptance_options_are_one_line_and_exit_2(tmp_path: Path) -> None:
    for args, words in ((["--dut", "colour=red"], "unknown key 'colour'"),
                        (["--declared", "nope.toml"], "--declared nope.toml"),
                        (["--dut-file", "nope.toml"], "--dut-file nope.toml")):
        done = cli(tmp_path, "run", "--cases", "A4-*", "--report-dir", "r", *args, timeout=60)
        assert done.returncode == 2 and words in done.stderr and "Traceback" not in done.stderr, done.stderr
        assert not (tmp_path / "r").exists()
    done = cli(tmp_path, "verify", tmp_path / "nothing", timeout=60)
    assert done.returncode == 2 and "no such directory" in done.stderr


def test_certify_robot_writes_one_verifiable_package(tmp_path: Path) -> None:
    """certify-robot --report-dir: the pcaps inside, the robot named, the manifest sealed."""
    proc = subprocess.Popen([sys.executable, "-m", "conformance", "certify-robot", "--listen", "127.0.0.1:0",
                             "--wait", "20", "--quiet", "--report-dir", "pkg", "--rate-tolerance", "50",
                             "--jitter-tolerance", "300", "--dut", "vendor=FANUC,model=R-30iB Plus,serial=R42"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert proc.stdout is not None
    port = re.match(r"^listening tcp 127\.0\.0\.1:(\d+)", proc.stdout.readline().strip())
    assert port, proc.stderr.read() if proc.stderr else ""
    robot = subprocess.run([sys.executable, "-m", "conformance", "robot", "--target", f"127.0.0.1:{port[1]}",
                            "--duration", "0.4", "-q"], capture_output=True, text=True, timeout=30)
    out, err = proc.communicate(timeout=30)
    assert robot.returncode == 0 and proc.returncode == 0, out + err
    pkg = tmp_path / "pkg"
    assert (pkg / "pcaps" / "session-1.pcapng").is_file() and not (tmp_path / "pcaps").exists()
    doc = json.loads((pkg / "summary.json").read_text())
    assert doc["acceptance"]["dut"]["serial"] == "R42" and "manifest sha256: " in out
    assert all(c["pcap"] is None or not c["pcap"].startswith("/") for c in doc["cases"])
    done = cli(tmp_path, "verify", pkg, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith("OK: "), done.stdout + done.stderr


def test_monitor_writes_one_verifiable_package_with_its_ring(tmp_path: Path) -> None:
    """monitor --report-dir: the pcapng ring inside the package, sealed after monitor.json."""
    from conformance.endpoints.bundled import start_bundled
    from conformance.endpoints.robot import RobotSession, run_robot
    from conformance.protocol import DEFAULT_PROFILE

    box = start_bundled(DEFAULT_PROFILE)
    proc = subprocess.Popen([sys.executable, "-m", "conformance", "monitor", "--listen", "127.0.0.1:0", "--upstream",
                             str(box.target), "--report-dir", "pkg", "--duration", "4", "--quiet",
                             "--dut", "vendor=Acme,model=VB-200,serial=SN7,operator=A. Tester"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert first.startswith("listening tcp 127.0.0.1:"), first
        port = int(first.split()[2].rsplit(":", 1)[1])
        run_robot(RobotSession(("127.0.0.1", port), DEFAULT_PROFILE, duration=0.5))
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        box.stop()
    assert proc.returncode in (0, 1), err
    pkg = tmp_path / "pkg"
    assert list((pkg / "pcaps").glob("*.pcapng")) and not (tmp_path / "pcaps").exists()
    assert json.loads((pkg / "summary.json").read_text())["acceptance"]["dut"]["operator"] == "A. Tester"
    done = cli(tmp_path, "verify", pkg, timeout=60)
    assert done.returncode == 0 and "manifest sha256: " in out, done.stdout + out + err


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="pdftotext (poppler-utils) is not installed")
def test_every_printed_page_carries_the_run_id_and_page_x_of_y(tmp_path: Path) -> None:
    from tests.reportruns import chromium, print_to_pdf

    if chromium() is None:
        pytest.skip("headless Chromium is not installed (apt-get install chromium)")
    proc, pkg = run_package(tmp_path, "trust-header", "first_index = 0\n", "PROFILE-01", "F*", "A4-*")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    run_id = json.loads((pkg / "summary.json").read_text())["acceptance"]["run_id"]
    pages = print_to_pdf(pkg / "report.html", tmp_path / "report.pdf")
    text = subprocess.run(["pdftotext", "-layout", str(tmp_path / "report.pdf"), "-"], capture_output=True,
                          text=True, timeout=60, check=True).stdout
    printed = text.split("\f")[:pages]
    assert pages >= 2 and len(printed) == pages
    for n, page in enumerate(printed, 1):
        assert run_id in page and f"Page {n} of {pages}" in page, f"page {n}"
    first = printed[0]
    assert "Device under test" in first and "SN0042" in first and "Test system" in first
    assert "apply only to the item tested" in text
