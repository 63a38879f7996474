"""missionplan.cli: the command line, the one front door. Owns argparse and every subcommand: parses the
arguments into a typed request (a frozen dataclass per command), calls the library with it and prints.
Nothing below this package sees an argparse.Namespace or names a `--flag`: a library error names a
setting by what it means (missionplan.base.naming) and errors.py spells it as the option that gives it.
Bad input gives one line on stderr and exit 2; no option may be abbreviated (`--uav` is not `--uavs`).

The top of the layers (tests/test_layers.py): it may import anything, nothing imports it.
  app        the `missionplan` parser (every subcommand's, in order), main(): dispatch and the exit codes
  parsing    the parser class (one-line errors, no abbreviations, negative values), the installed version,
             arguments -> typed request
  errors     how a library error is said: each setting it names spelled as its option
  plan       `maps` (the shipped maps) and `plan` (a map or an area -> a plan folder)
  train      `train` (the neural policy's weights, by imitation of the expert)
  vehicle    `upload`, `download`, `clear` (MAVLink mission transfer), and the link options fly shares
  mock       `mock` (mock autopilots on loopback, a serial device or a pty)
  fly        `fly` (fly a planned fleet, journal it, judge it)
  survey     `status` (the survey's ledger) and `replan` (plan what the survey still misses)
  demo       `demo` (plan + mock fleet + fly, in one command)
`missionplan --version` prints the installed version.
"""

from .app import main

__all__ = ["main"]
