"""A vanished robot's connections (issue 38): abandoned without FIN or RST, reset when released, and
noticed when the box closes them itself; a planted vanish and reset against the bundled box."""

from __future__ import annotations

import asyncio
import socket

import pytest

from conformance.endpoints.bundled import start_bundled
from conformance.endpoints.robot.robot_io import Link
from conformance.protocol import DEFAULT_PROFILE
from conformance.soak.sessions import Ghosts, SoakSession


def listener() -> socket.socket:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    server.settimeout(5)
    return server


async def open_link(port: int) -> Link:
    link = Link("cmd", DEFAULT_PROFILE, lambda now, event: None, lambda: None)
    await asyncio.get_running_loop().create_connection(lambda: link, "127.0.0.1", port)
    return link


def test_an_abandoned_connection_sends_nothing_until_released_with_an_rst():
    server = listener()
    ghosts = Ghosts(hold_s=60)

    async def scenario() -> socket.socket:
        link = await open_link(server.getsockname()[1])
        peer, _ = server.accept()
        ghosts.keep(link)
        await asyncio.sleep(0.2)  # asyncio's transport is closed by now: only the duplicate holds the connection
        return peer

    peer = asyncio.run(scenario())
    try:
        peer.settimeout(0.5)
        with pytest.raises(TimeoutError):
            peer.recv(1)  # no FIN (b"") and no RST: the box sees a silent, open connection
        assert ghosts.abandoned == 1 and len(ghosts.ring) == 1
        ghosts.release_all()
        with pytest.raises(ConnectionResetError):
            peer.recv(1)
        assert ghosts.released == 1 and not ghosts.ring
    finally:
        peer.close()
        server.close()


def test_a_ghost_the_box_closes_is_counted_as_freed_by_the_box():
    server = listener()
    ghosts = Ghosts(hold_s=60)

    async def scenario() -> None:
        link = await open_link(server.getsockname()[1])
        peer, _ = server.accept()
        ghosts.keep(link)
        peer.close()  # the box frees the half-open connection (an idle time-out, say)
        await asyncio.sleep(0.2)
        ghosts.sweep()

    try:
        asyncio.run(scenario())
    finally:
        server.close()
    assert ghosts.freed_by_box == 1 and not ghosts.ring
    assert ghosts.to_dict()["freed_after_s_median"] is not None


def test_the_ring_is_bounded_and_releases_the_oldest():
    server = listener()
    ghosts = Ghosts(hold_s=60, most=2)

    async def scenario() -> list[socket.socket]:
        peers = []
        for _ in range(3):
            link = await open_link(server.getsockname()[1])
            peers.append(server.accept()[0])
            ghosts.keep(link)
        return peers

    peers = asyncio.run(scenario())
    try:
        assert len(ghosts.ring) == 2 and ghosts.released == 1
        with pytest.raises(ConnectionResetError):
            peers[0].recv(1)
    finally:
        ghosts.release_all()
        for peer in peers:
            peer.close()
        server.close()


@pytest.mark.parametrize("event", ["vanish", "reset", "stall"])
def test_a_planted_event_mid_cycle_against_the_bundled_box(event):
    box = start_bundled(DEFAULT_PROFILE)
    ghosts = Ghosts(hold_s=60)
    try:
        target = (box.target.host, box.target.port)
        session = SoakSession(target, DEFAULT_PROFILE, robot=0, duration=0.6, extension=True, event=event,
                              event_at=0.5, stall_s=0.3, ghosts=ghosts, result_wait=0.1)
        asyncio.run(session.run())
        outcome = session.outcome(5000)
        after = SoakSession(target, DEFAULT_PROFILE, robot=0, duration=0.3, extension=True, after_event=event,
                            ghosts=ghosts, result_wait=0.1)
        asyncio.run(after.run())
        served = after.outcome(5000)
    finally:
        ghosts.release_all()
        box.stop()
    assert outcome.ok and outcome.event == event
    if event == "stall":
        assert outcome.poses_answered == outcome.poses_sent > 0  # every pose answered, before and after the stall
    else:
        assert session.result.reason.startswith("planted")
    assert ghosts.abandoned == (2 if event == "vanish" else 0)
    assert served.ok and served.after_event == event  # the rebooted robot, from new ports, is served


def test_an_unreachable_target_or_a_missing_process_is_one_line_and_exit_2(capsys, tmp_path):
    from conformance.commands import main

    free = socket.socket()
    free.bind(("127.0.0.1", 0))
    port = free.getsockname()[1]
    free.close()  # nothing listens there now
    assert main(["soak", "--duration", "30s", "--target", f"127.0.0.1:{port}", "--report-dir", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("isight-conformance soak: target") and "refused" in err and "\n" not in err
    assert not (tmp_path / "r").exists()  # nothing was written for a soak that never started
    box = start_bundled(DEFAULT_PROFILE)
    try:
        code = main(["soak", "--duration", "30s", "--target", str(box.target), "--box-pid", "999999999"])
    finally:
        box.stop()
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--box-pid 999999999" in err and "\n" not in err
