"""What one run holds for one box: the resolved settings (:mod:`.settings`, :mod:`.profile_options`) and the
session's state (:mod:`.run_state`: liveness, what was learnt about the box). Below :mod:`conformance.suite`:
the case author's context reads it; it reads nothing of the cases."""
