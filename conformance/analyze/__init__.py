"""``isight-conformance analyze``: judge a capture of real robot ↔ box traffic, both roles.

The capture streams through :mod:`.capture` (pcap/pcapng), :mod:`.capture_packets` (headers),
:mod:`.conversations` (which conversations are iSight, who is the robot),
:mod:`.reassembly` (TCP in order, gaps), :mod:`.framing` (the codec's frames),
:mod:`.exchanges` (each connection's requests and answers) and :mod:`.sessions` (S1/E4,
A1, S5 across connections); :mod:`.report` turns the findings into the suite's reports.
"""

from .analysis_context import AnalyzeConfig
from .analysis_report import build_cases, write_analysis
from .capture import CaptureError
from .engine import Analysis, analyze

__all__ = ["Analysis", "AnalyzeConfig", "CaptureError", "analyze", "build_cases", "write_analysis"]
