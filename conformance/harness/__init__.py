"""I/O side of the suite: recorded connections to a target box, and their transcripts."""
