"""geo: world <-> grid (camera footprint, projection, rasterising, area files). Filled by issue 4."""
