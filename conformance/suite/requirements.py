"""The requirements several cases share, declared once (a case's own requirements stay beside it)."""

from __future__ import annotations

from ..harness.client import Answer
from .case_judge import answered, answered_allowed
from .record import Expect, Requirement

#: A1: the request whose answer a case inspects is answered 0000 (the codes PROTOCOL.md allows)
ANSWERED_0 = Requirement(("A1",), "a well-formed {action.name} request is answered",
                         accept=lambda action, **_: answered_allowed(action))
#: A1: a well-formed request is answered (any code)
ANSWERED = Requirement(("A1",), "a well-formed {action.name} request is answered", accept=lambda action, **_: answered(action))
#: the words of every "not a request" requirement
NOT_0000 = "MUST NOT be answered 0000"
#: the outcome of a frame the box did not answer (silence, a close, or malformed bytes)
NOT_ANSWERED = Expect("not answered", lambda o: not isinstance(o, Answer))
