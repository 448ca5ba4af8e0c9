"""The result model: verdicts, levels, case records, root causes and exit statuses; the bottom of the house."""
