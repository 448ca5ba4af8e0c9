"""Shared test configuration: hypothesis profiles.

``dev`` (default) keeps hypothesis's example database in .hypothesis/; ``ci`` (set
HYPOTHESIS_PROFILE=ci, as .ci/run does) runs derandomised with no deadline so a CI
run is reproducible on a loaded 2-core machine.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile("dev", deadline=None)
settings.register_profile(
    "ci", deadline=None, derandomize=True, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))
