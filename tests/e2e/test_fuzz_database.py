"""The fuzz example database (conformance/fuzz/database.py): directories, none, redis, and a read-only
shared store through which a failure found on one machine replays on another.

The redis tests start their own ``redis-server`` on 127.0.0.1 on a free port; without the
redis-server binary or the redis package they skip, saying which is missing.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis.database import DirectoryBasedExampleDatabase, MultiplexedDatabase, ReadOnlyDatabase

from conformance.commands import main
from conformance.fuzz.database import redact, resolve_database
from tests.integration.test_fuzz_campaign import SHRUNK_BAD_INDEX, patched_box, zero_to_bad_pose_index

pytestmark = pytest.mark.timeout(240)

#: redis commands that change data; the shared store must see none of them
WRITES = ("sadd", "srem", "del", "unlink", "set", "smove", "flushdb", "flushall", "rename", "hset")


# -- without a server ---------------------------------------------------------------------------------


def test_directories_none_and_a_read_only_shared_directory(tmp_path: Path) -> None:
    assert resolve_database("none") == (None, "off (--database none)")
    db, label = resolve_database(str(tmp_path / "a"))
    assert isinstance(db, DirectoryBasedExampleDatabase) and label == str(tmp_path / "a")
    db, label = resolve_database(str(tmp_path / "a"), str(tmp_path / "shared"))
    assert isinstance(db, MultiplexedDatabase) and label.endswith("(shared, read-only)")
    db, label = resolve_database("none", str(tmp_path / "shared"))
    assert isinstance(db, ReadOnlyDatabase) and "nothing is saved" in label


def test_a_shared_directory_is_replayed_and_never_written(tmp_path: Path) -> None:
    shared = DirectoryBasedExampleDatabase(tmp_path / "shared")
    shared.save(b"key", b"found-on-ci")
    db, _ = resolve_database(str(tmp_path / "local"), str(tmp_path / "shared"))
    assert set(db.fetch(b"key")) == {b"found-on-ci"}
    db.save(b"key", b"found-here")
    db.delete(b"key", b"found-on-ci")
    assert set(shared.fetch(b"key")) == {b"found-on-ci"}  # untouched
    assert set(DirectoryBasedExampleDatabase(tmp_path / "local").fetch(b"key")) == {b"found-here"}


def test_bad_stores_are_one_line_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="not a directory"):
        resolve_database(str(tmp_path / "file"))
    with pytest.raises(ValueError, match="--database-shared none"):
        resolve_database("none", "none")
    code = main(["fuzz", "--max-examples", "5", "--database", "redis://127.0.0.1:1/0", "--report-dir",
                 str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2
    if "needs the redis package" not in err:
        assert err.startswith("isight-conformance fuzz: --database redis://127.0.0.1:1/0: redis does not answer")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "r").exists()  # nothing created for a run that never started


def test_without_the_redis_package_the_error_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "redis", None)  # import redis -> ImportError
    monkeypatch.delitem(sys.modules, "hypothesis.extra.redis", raising=False)
    with pytest.raises(ValueError, match=r"pip install 'isight-conformance\[redis\]'"):
        resolve_database("redis://127.0.0.1:6379/0")


def test_passwords_are_not_printed() -> None:
    assert redact("redis://:s3cret@ci-redis:6379/2") == "redis://:***@ci-redis:6379/2"
    assert redact("redis://ci-redis:6379/2") == "redis://ci-redis:6379/2"


# -- against a real redis-server ----------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def redis_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A throwaway redis-server on 127.0.0.1 (no persistence), killed at teardown."""
    binary = shutil.which("redis-server")
    if binary is None:
        pytest.skip("redis-server is not installed (Debian: apt-get install redis-server)")
    try:
        import redis
    except ImportError:
        pytest.skip("the redis package is not installed (pip install 'isight-conformance[redis]')")
    workdir = tmp_path_factory.mktemp("redis")
    for _attempt in range(3):  # the free port may be taken between probe and bind: try another
        port = _free_port()
        proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly",
                                 "no", "--dir", str(workdir)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        client = redis.Redis(host="127.0.0.1", port=port, socket_timeout=2, socket_connect_timeout=2)
        deadline = time.monotonic() + 15
        up = False
        while time.monotonic() < deadline and proc.poll() is None:
            with contextlib.suppress(redis.RedisError):
                up = bool(client.ping())
                break
            time.sleep(0.05)
        client.close()
        if up:
            try:
                yield f"redis://127.0.0.1:{port}/0"
            finally:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=10)
            return
        proc.kill()
        proc.wait(timeout=10)
    pytest.fail("redis-server did not answer PING within 15 s (three ports tried)")


def _client(url: str) -> Any:
    import redis

    return redis.Redis.from_url(url, socket_timeout=5)


def _snapshot(client: Any) -> dict[bytes, set[bytes]]:
    return {key: set(client.smembers(key)) for key in client.scan_iter(match=b"hypothesis-example:*")}


def _writes(client: Any) -> dict[str, int]:
    stats = client.info("commandstats")
    return {cmd: int(stats.get(f"cmdstat_{cmd}", {}).get("calls", 0)) for cmd in WRITES}


def _fuzz(target: str, out: Path, seed: int, *database: str) -> tuple[int, dict[str, Any]]:
    # --categories: hypothesis's own cases only (no boundary schedule, whose finds are not saved: it runs first anyway)
    code = main(["fuzz", "--target", target, "--max-examples", "3000", "--seed", str(seed), "--stateful-share", "0",
                 "--categories", "valid,F2-version,F3-direction,B4-floats,mutation,F1-garbage", "--max-failures", "1", "--report-dir", str(out / "r"), "--pcap-dir", str(out / "p"), "--quiet",
                 *database])
    return code, json.loads((out / "r" / "fuzz-summary.json").read_text())


def test_a_redis_database_stores_what_a_campaign_finds(redis_url: str) -> None:
    db, label = resolve_database(redis_url)
    assert type(db).__name__ == "RedisExampleDatabase" and label == redis_url
    db.save(b"isight-test-key", b"value")
    assert set(db.fetch(b"isight-test-key")) == {b"value"}
    db.delete(b"isight-test-key", b"value")
    assert set(db.fetch(b"isight-test-key")) == set()


def test_a_failure_found_on_one_machine_replays_on_another_through_the_shared_store(
        redis_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    client = _client(redis_url)
    client.flushdb()
    with patched_box(zero_to_bad_pose_index) as box:
        target = f"127.0.0.1:{box.tcp_port}"
        # "CI": finds the planted defect and saves it in redis
        code, ci = _fuzz(target, tmp_path / "ci", 3, "--database", redis_url)
        assert code == 1 and ci["failures"], capsys.readouterr().out
        assert ci["database"] == redis_url
        assert ci["failures"][0]["found_after"] > 32  # found by generation, not replayed
        saved = _snapshot(client)
        assert saved and any(saved.values())
        writes_before = _writes(client)

        # a developer, another seed: without the shared store the defect takes a while to find ...
        code, alone = _fuzz(target, tmp_path / "alone", 99, "--database", "none")
        assert code == 1 and alone["failures"][0]["found_after"] > 32
        # ... with it, it is replayed first, from the shared store
        local = tmp_path / "dev-db"
        code, dev = _fuzz(target, tmp_path / "dev", 99, "--database", str(local), "--database-shared", redis_url)
        assert code == 1, capsys.readouterr().out
    (failure,) = dev["failures"]
    assert failure["found_after"] <= 32  # the first hypothesis example: the replayed one
    assert failure["cases"][0]["hex"] == SHRUNK_BAD_INDEX
    assert dev["database"] == f"{local} + {redis_url} (shared, read-only)"
    # nothing was written to the shared store; the find was saved locally
    assert _snapshot(client) == saved
    assert _writes(client) == writes_before
    assert any(p.is_file() for p in local.rglob("*"))
    client.close()
