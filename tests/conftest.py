import sys
from pathlib import Path

# Let tests import the small checkers that live beside them, and the loopback helpers (free ports,
# bounded waits) that the integration tests in sitl_tests/ use too.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "sitl_tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from loopback import let_children_hear_ctrl_c  # noqa: E402  (found through the path above)

let_children_hear_ctrl_c()
