"""The one error type of the geo package.

Every wrong input (file, polygon, camera number, launch point) ends up as a `GeoError`
whose message is one line naming the file or the value and the problem, so the CLI can
print it as-is instead of a traceback.
"""

from __future__ import annotations


class GeoError(ValueError):
    """Wrong geographic input; the one-line message names the file or value and the problem."""
