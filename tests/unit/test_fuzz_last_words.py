"""The box's last words (pure): headlines of sanitizer reports, tracebacks, crash lines and signals."""

from __future__ import annotations

from conformance.fuzz.last_words import LastWords, excerpt, headline, last_words, signal_of, telling

ASAN = """listening 9100
=================================================================
==1540==ERROR: AddressSanitizer: heap-buffer-overflow on address 0x6030000018ee at pc 0x7f0a bp 0x7f0a sp 0x7f0a
WRITE of size 35 at 0x6030000018ee thread T1
    #0 0x7f0ac8848060 in __interceptor_memcpy ../../../../src/libsanitizer/sanitizer_common_interceptors.inc:827
    #1 0x55e71256ee5b in store_tolerances tests/impls/asan_box.c:59
    #2 0x55e71256ee5b in handle tests/impls/asan_box.c:100
SUMMARY: AddressSanitizer: heap-buffer-overflow sanitizer_common_interceptors.inc:827 in __interceptor_memcpy
Shadow byte legend (one shadow byte represents 8 application bytes):
  Addressable:           00
==1540==ABORTING
"""

TRACEBACK = """listening 9100
Traceback (most recent call last):
  File "box.py", line 75, in serve
    decide(event)
  File "box.py", line 59, in _watch
    raise PlantedDeath("pose after CycleOff on another connection")
PlantedDeath: pose after CycleOff on another connection
"""


def test_asan_report_names_the_bug_the_access_and_the_boxs_own_frame():
    kind, line = headline(ASAN, 1)
    assert kind == "asan"
    assert line == "AddressSanitizer: heap-buffer-overflow (WRITE of size 35) in store_tolerances tests/impls/asan_box.c:59"


def test_ubsan_runtime_error_is_the_headline():
    text = "ok\nbox.c:31:12: runtime error: signed integer overflow: 2147483647 + 1 cannot be represented\nmore\n"
    assert headline(text, None) == ("ubsan", "box.c:31:12: runtime error: signed integer overflow: 2147483647 + 1 "
                                             "cannot be represented")


def test_python_traceback_headline_is_its_exception_line():
    assert headline(TRACEBACK, 70) == ("traceback", "Python traceback: PlantedDeath: pose after CycleOff on another "
                                                    "connection")


def test_segfault_line_beats_the_exit_status():
    assert headline("serving\n/bin/sh: line 1:  4242 Segmentation fault      (core dumped) ./box 9100\n", 139) == (
        "crash", "/bin/sh: line 1:  4242 Segmentation fault      (core dumped) ./box 9100")


def test_signals_from_popen_and_through_a_shell():
    assert signal_of(-11) == "SIGSEGV"
    assert signal_of(134) == "SIGABRT"
    assert signal_of(0) is None and signal_of(1) is None and signal_of(None) is None
    assert headline("", -9) == ("signal", "killed by SIGKILL")
    assert headline("", 3) == ("exit", "exited with status 3")
    assert headline("all fine\n", 0) == ("", "")
    assert headline("all fine\n", None) == ("running", "")


def test_excerpt_is_the_report_head_or_the_traceback():
    asan = last_words(2, 99, 1, ASAN.encode())
    lines = excerpt(asan, 4)
    assert lines[0].startswith("==1540==ERROR: AddressSanitizer") and len(lines) == 4
    tb = last_words(1, 98, 70, TRACEBACK.encode())
    assert excerpt(tb)[0] == "Traceback (most recent call last):"
    assert excerpt(tb)[-1] == "PlantedDeath: pose after CycleOff on another connection"
    assert "listening" not in " ".join(excerpt(tb))


def test_summary_and_dict():
    words = last_words(3, 1234, -11, b"\xff\xfebinary junk\nSegmentation fault\n", truncated=True)
    assert words.summary() == "the box (incarnation 3, pid 1234) exit status -11, SIGSEGV: Segmentation fault"
    d = words.to_dict()
    assert d["signal"] == "SIGSEGV" and d["truncated"] is True and "\ufffd" in d["tail"]


def test_shown_tail_keeps_the_end_at_a_line_boundary():
    words = last_words(1, 1, 1, ("x" * 50 + "\n").encode() * 200)
    shown = words.shown_tail(500)
    assert shown.startswith("…x") and len(shown) <= 501 and shown.endswith("x\n")


def test_telling_prefers_a_headline():
    quiet = LastWords(1, 1, 0, None, "", "", "")
    loud = last_words(2, 2, 1, ASAN.encode())
    assert telling([None, quiet, loud]) is loud
    assert telling([quiet, None]) is quiet
    assert telling([None]) is None
