"""The bridge's two kinds of failure, so that callers (the CLI above all) can tell them apart.

BridgeUsageError: the input is wrong (missing file, bad connection URL, bad system id, bad key file).
The message is one line that names the culprit; the CLI prints it and exits 2.
BridgeError: the input was fine but the vehicle or the link let us down (no heartbeat, a mission
protocol error, a read-back that differs). The CLI prints it and exits 1.
"""

from __future__ import annotations


class BridgeUsageError(ValueError):
    """Bad input: a one-line message naming the file, URL or option that is wrong."""


class BridgeError(RuntimeError):
    """An operational failure talking to a vehicle: a one-line message saying what happened."""
