"""The process pool's worker (`python -m missionplan.verify.worker`): one run, its job as JSON on stdin, its row as
one JSON line on stdout (the last line; what fly says goes to the run's run.log). A worker killed mid-run ends
without that line: the pool (engines.run_pool) retries the run once."""

from __future__ import annotations

import json
import sys

from .engines import job_from_json
from .flight_run import fly_run


def main() -> int:
    job = job_from_json(json.loads(sys.stdin.read()))
    row = fly_run(job)
    sys.stdout.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
