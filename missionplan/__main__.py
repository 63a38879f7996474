"""`python -m missionplan` runs the command line."""

from .cli.app import main

# The guard matters: `missionplan train` starts worker processes with "spawn", which
# re-imports this module in every worker; only the real entry point may run main().
if __name__ == "__main__":
    raise SystemExit(main())
