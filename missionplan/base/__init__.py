"""missionplan.base: what every layer shares, below them all.

May import: nothing from missionplan (tests/test_layers.py), so that geo, maps and learn need nothing from
bridge to write a file, and bridge needs nothing from the planner.

  atomic          atomic file output: write a temp file beside the target, then rename
  naming          how a library error names a setting the user gave: by what it means, spelled by the front end
"""
