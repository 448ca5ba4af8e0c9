"""isight-conformance: conformance and fuzz test suite for the iSight socket protocol."""

__version__ = "0.1.0"
