"""The conformance suite's model: verdicts, case metadata, results."""
