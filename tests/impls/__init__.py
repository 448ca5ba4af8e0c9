"""Independent iSight implementations the conformance suite is proven against.

Written from PROTOCOL.md alone, without importing anything from ``conformance``:
boxes (server role, ``python -m tests.impls.box``), robots (client role,
``python -m tests.impls.robot``) and the matrix that runs the suite against each
(``python -m tests.impls.matrix``). Their legal choices are knobs (``policy.KNOBS``,
``robots.KNOBS``), one per row of docs/LEGAL-CHOICES.md; ``random --seed N`` is a
random legal combination and ``matrix --sample N`` runs many. Loopback only.
"""
