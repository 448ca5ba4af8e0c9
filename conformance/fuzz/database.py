"""The fuzz campaign's example database, from ``--database`` and ``--database-shared``.

Hypothesis saves every failing example (shrunk) in its example database and replays
the saved ones first on the next run. ``--database`` names the campaign's own store:

* a directory (``DirectoryBasedExampleDatabase``; the default ``.hypothesis/isight-fuzz``),
* ``none`` (no database),
* ``redis://[:PASSWORD@]HOST:PORT/DB`` (``hypothesis.extra.redis.RedisExampleDatabase``;
  needs the ``redis`` package: ``pip install 'isight-conformance[redis]'``), so that
  several machines share one corpus.

``--database-shared URL`` (a redis URL or a directory) adds a store that is only read:
``MultiplexedDatabase(local, ReadOnlyDatabase(shared))``. A developer replays what CI
found (and saves new finds locally) without ever writing to CI's store. With
``--database none`` and a shared store, the campaign replays the shared store only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from hypothesis.database import (
    DirectoryBasedExampleDatabase,
    ExampleDatabase,
    MultiplexedDatabase,
    ReadOnlyDatabase,
)

#: Where the example database lives by default (relative to the current directory).
DEFAULT_DATABASE = Path(".hypothesis") / "isight-fuzz"
#: how long to wait for a redis server to answer before calling it unreachable
REDIS_TIMEOUT_S = 5.0
REDIS_SCHEMES = ("redis", "rediss", "unix")


def is_redis_url(value: str) -> bool:
    return urlsplit(value).scheme.lower() in REDIS_SCHEMES and "://" in value


def redact(url: str) -> str:
    """A redis URL fit to print: the password, if any, replaced by ``***``."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    user = parts.username or ""
    netloc = f"{user}:***@{parts.hostname or ''}" + (f":{parts.port}" if parts.port else "")
    return urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))


def open_redis(url: str, flag: str = "--database") -> ExampleDatabase:
    """A RedisExampleDatabase on ``url``, checked with a PING; ValueError with one clear line
    when the redis package is missing, the URL is malformed or the server does not answer."""
    try:
        import redis
        from hypothesis.extra.redis import RedisExampleDatabase
    except ImportError:
        raise ValueError(f"{flag} {redact(url)}: a redis database needs the redis package: "
                         "pip install 'isight-conformance[redis]'") from None
    try:
        client = redis.Redis.from_url(url, socket_timeout=REDIS_TIMEOUT_S, socket_connect_timeout=REDIS_TIMEOUT_S)
    except ValueError as exc:
        raise ValueError(f"{flag} {redact(url)}: not a redis URL ({exc})") from None
    try:
        client.ping()
    except redis.RedisError as exc:
        client.close()
        raise ValueError(f"{flag} {redact(url)}: redis does not answer: {exc}") from None
    return RedisExampleDatabase(client)


def open_store(value: str, flag: str = "--database") -> tuple[ExampleDatabase, str]:
    """(database, label) for one store: a redis URL or a directory."""
    if is_redis_url(value):
        return open_redis(value, flag), redact(value)
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{flag} {value}: not a directory")
    return DirectoryBasedExampleDatabase(path), str(path)


def resolve_database(value: str | None, shared: str | None = None) -> tuple[Any, str]:
    """(ExampleDatabase or None, how to describe it) from ``--database`` and ``--database-shared``.

    Without ``--database`` the default directory is used, or none when the active
    hypothesis profile (e.g. its built-in ``ci`` profile) has its database switched off.
    Raises ValueError with one clear line for a store that cannot be used.
    """
    from hypothesis import settings

    local: ExampleDatabase | None
    if value is not None and value.strip().lower() == "none":
        local, label = None, "off (--database none)"
    elif value is None and settings.default is not None and settings.default.database is None:
        local = None
        label = f"off (the active hypothesis profile {settings.get_current_profile_name()!r} has no database)"
    else:
        local, label = open_store(value or str(DEFAULT_DATABASE))
    if not shared:
        return local, label
    if shared.strip().lower() == "none":
        raise ValueError("--database-shared none: give a redis URL or a directory (or leave the option out)")
    store, shared_label = open_store(shared, "--database-shared")
    read_only = ReadOnlyDatabase(store)
    if local is None:
        return read_only, f"{shared_label} (shared, read-only; nothing is saved)"
    return MultiplexedDatabase(local, read_only), f"{label} + {shared_label} (shared, read-only)"
