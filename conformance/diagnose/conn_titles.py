"""Titles of the connection-state mechanisms (:mod:`.conn_state`, :mod:`.conn_deaths`): one line each, what the
box does with the number an experiment measured (seconds idle, seconds open, connections closed), the clause, and
after a dash the direction of the fix. Every string is translatable (zh-CN in ``conformance/i18n``)."""

from __future__ import annotations

from ..i18n import gettext
from .titles import name


def seconds(s: float) -> str:
    """A measured time as a title writes it: one decimal ("3.0")."""
    return f"{s:.1f}"


def idle_close(idle_s: float, busy_s: float, gap_s: float, action: int | None) -> str:
    """An idle connection closed after ``idle_s`` while one carrying a request every ``gap_s`` stayed open
    ``busy_s``."""
    at = (gettext("; {action} sent at once on a fresh connection is answered and the connection kept open").format(
        action=name(action)) if action is not None else "")
    return gettext("Closes any connection idle for {t} s (a NONE answered, then silence: closed after {t} s; a "
                   "connection sent a NONE every {gap} s stayed open {busy} s{at}): S1/S4 keep the command connection "
                   "open though it is silent for a whole trajectory — do not close a connection for being "
                   "idle").format(t=seconds(idle_s), busy=seconds(busy_s), gap=seconds(gap_s), at=at)


def peer_close(action: int) -> str:
    """Connection A closed after ``action`` on connection B (NONE: B merely opened)."""
    if action == -1:  # conn_peers.STREAM_CLOSED
        return gettext("Closes the command connection when the stream connection closes (connection A closed once "
                       "connection B, which had sent a pose, closed): the robot ends the stream (Send_Pos_Off) and "
                       "keeps its command connection until ISIGHT(2) (S1, E4) — close only the connection the robot "
                       "closes")
    if action == 0:
        return gettext("Closes a connection when another one opens (connection A closed once connection B connected "
                       "and had a NONE answered): S4 asks for the command and stream connections served at once — "
                       "keep every open connection")
    return gettext("Closes the other open connections at {action} (connection A closed after {action} on connection "
                   "B): S1/S4 keep the command and stream connections open through a cycle — close only the "
                   "connection the robot closes").format(action=name(action))


def open_limit(n: int) -> str:
    """A new connection not served while ``n`` are open; served again once they closed."""
    return gettext("Stops serving new connections once {n} connections are held open by the experiment (besides any the "
                   "suite still holds), and serves a fresh one again once they close (a fixed table of open "
                   "connections?): R5 asks that connections held open never stop the box serving others — serve more "
                   "connections at once").format(n=n)


def age_close(idle_s: float, busy_s: float) -> str:
    """Every connection closed about ``idle_s`` after it opened, even one carrying requests (closed at ``busy_s``)."""
    return gettext("Closes every connection about {t} s after it opened, even while requests flow on it (an idle one "
                   "closed after {t} s, a busy one after {busy} s): S1/S4 keep the command connection open until the "
                   "robot disconnects — do not limit a connection's lifetime").format(
        t=seconds(idle_s), busy=seconds(busy_s))


def leak_count(opened: int, closed: int, case: str, why: str) -> str:
    """New connections refused once ``closed`` connections have closed; the input story ruled out by ``why``."""
    return gettext("Stops accepting new connections after the suite had opened {opened} connections and closed "
                   "{closed}: the state of closed connections is never freed (a fixed table?), rather than the input of "
                   "case {case} ({why}): S5 asks for new connections served however many came before — free a "
                   "connection's state when it closes").format(closed=closed, opened=opened, case=case, why=why)


def leak_or_input(opened: int, closed: int, case: str) -> str:
    """Two stories one death cannot tell apart without a restart."""
    return gettext("Stops accepting new connections after the input of case {case}, or once {closed} connections have "
                   "closed ({opened} opened) and their state was never freed: one death without a restart cannot tell "
                   "the two apart (S5, R2)").format(case=case, closed=closed, opened=opened)


def same_kind_passed(n: int, test: str) -> str:
    return gettext("{n} earlier case(s) of the same test {test} sent inputs of its kind and the box went on accepting "
                   "connections").format(n=n, test=test)


def nothing_unusual() -> str:
    return gettext("that case sent only valid requests")
