"""``monitor --http``: the live page in a real headless Chromium (issue 26).

The page is loaded from the monitor while a robot talks lock-step to a box through it;
then the box goes silent. The page must show the alarm (box silent past time_out, T1)
within 2 s of the box going silent, pushed by server-sent events, without a reload.
The page also comes in Chinese (``--lang zh-CN``) and refuses nothing but GET.
"""

from __future__ import annotations

import asyncio
import dataclasses
import time
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from conformance.i18n import language
from conformance.protocol import DEFAULT_PROFILE, Action, answer, encode, request
from tests.monitor_util import monitored

from .cdp_util import CHROMIUM, Browser

TIME_OUT_MS = 500
FAST = dataclasses.replace(DEFAULT_PROFILE, time_out_ms=TIME_OUT_MS)
NONE = encode(request(Action.NONE))


class SwitchBox:
    """Answers each 14-byte request at once until ``silent`` is set, then reads and says nothing."""

    def __init__(self) -> None:
        self.silent = False
        self.server: asyncio.AbstractServer | None = None

    async def start(self) -> int:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return int(self.server.sockets[0].getsockname()[1])

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                data = await reader.readexactly(14)
                if not self.silent:
                    writer.write(encode(answer(Action(data[5]))))
        except (asyncio.IncompleteReadError, ConnectionError):
            writer.close()


async def _robot(target: tuple[str, int], stop: asyncio.Event) -> None:
    """Lock-step NONE requests every 100 ms; after an unanswered one it waits (as the robot's time_out would)."""
    reader, writer = await asyncio.open_connection(*target)
    try:
        while not stop.is_set():
            writer.write(NONE)
            try:
                await asyncio.wait_for(reader.readexactly(14), 30)
            except (asyncio.TimeoutError, TimeoutError, asyncio.IncompleteReadError):
                return
            await asyncio.sleep(0.1)
    finally:
        writer.close()


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="chromium is not installed (Debian package chromium)")
def test_the_page_shows_a_silent_box_within_two_seconds(tmp_path: Path) -> None:
    async def main() -> dict[str, Any]:
        box = SwitchBox()
        port = await box.start()
        async with monitored(port, tmp_path, profile=FAST, http=("127.0.0.1", 0)) as m:
            assert m.settings.http is not None
            url = f"http://127.0.0.1:{m.settings.http[1]}/"
            stop = asyncio.Event()
            robot = asyncio.ensure_future(_robot(m.target, stop))
            try:
                return await asyncio.to_thread(_watch, tmp_path, url, box)
            finally:
                stop.set()
                robot.cancel()
                assert box.server is not None
                box.server.close()

    got = asyncio.run(main())
    assert got["before"] is None, "an alarm before the box went silent"
    assert got["first_alarm_ms"] is not None, "no alarm on the page within 10 s"
    delay = got["first_alarm_ms"] / 1000.0 - got["silent_at"]
    print(f"the alarm appeared on the page {delay:.2f} s after the box went silent (time_out {TIME_OUT_MS} ms)")
    assert 0 < delay < 2.0, f"the alarm appeared {delay:.2f} s after the box went silent"
    assert "T1" in got["text"] and "box-silent" in got["text"] and "NONE" in got["text"]
    assert got["kind"] == "box-silent"


def _watch(tmp_path: Path, url: str, box: SwitchBox) -> dict[str, Any]:
    with Browser(tmp_path) as b:
        b.open(url)
        assert b.wait_for("document.body && document.body.dataset.version", 30), "the page got no event"
        assert b.wait_for("document.querySelector('#summary td') !== null", 10)
        time.sleep(0.8)  # answered requests flow; no alarm
        before = b.evaluate("window.firstAlarmAt")
        box.silent = True
        silent_at = time.time()
        first = b.wait_for("window.firstAlarmAt", 10)
        text = b.evaluate("(document.querySelector('#alarms .alarm.active') || {}).textContent")
        kind = b.evaluate("(document.querySelector('#alarms .alarm.active') || {dataset: {}}).dataset.kind")
        return {"before": before, "silent_at": silent_at, "first_alarm_ms": first, "text": text or "", "kind": kind}


def test_the_page_in_chinese_and_only_get(tmp_path: Path) -> None:
    async def main() -> tuple[str, str, int]:
        box = SwitchBox()
        port = await box.start()
        with language("zh-CN"):
            async with monitored(port, tmp_path, http=("127.0.0.1", 0)) as m:
                assert m.settings.http is not None
                base = f"http://127.0.0.1:{m.settings.http[1]}"
                page = await asyncio.to_thread(_fetch, base + "/")
                state = await asyncio.to_thread(_fetch, base + "/state.json")
                status = await asyncio.to_thread(_post, base + "/")
        assert box.server is not None
        box.server.close()
        return page, state, status

    page, state, status = asyncio.run(main())
    assert '<html lang="zh-CN">' in page and "连接" in page  # "connections", from the catalogue
    assert "http://" not in page.split("<script>")[1].split("</script>")[0]  # nothing loaded from elsewhere
    assert '"connections"' in state
    assert status == 405


def _fetch(url: str) -> str:
    with urllib.request.urlopen(url, timeout=10) as r:
        return str(r.read().decode("utf-8"))


def _post(url: str) -> int:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, data=b"x", method="POST"), timeout=10) as r:
            return int(r.status)
    except urllib.error.HTTPError as exc:
        return int(exc.code)
