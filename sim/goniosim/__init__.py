"""goniosim: a simulated UBO-type gonioreflectometer for testing goniowatch.

The controller speaks docs/protocol.md over a real pseudo-terminal, renders HDR captures from
the true pose (after injected faults) and writes a ground-truth file for tests and benchmarks.
"""

__version__ = "1.0.0"
