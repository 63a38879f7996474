"""missionplan.base: what every layer may use, importing nothing of missionplan (below bridge, the lowest layer).

  naming   how a library error names a setting the user gave: by what it means, spelled by the front end
"""
