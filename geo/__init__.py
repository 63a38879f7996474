"""missionplan.geo: world <-> grid (camera footprint, projection, rasterising, area files, GIS files).

Installed as missionplan.geo from the repository's geo/ folder. May import: missionplan.bridge.atomic (atomic
writes), nothing else from missionplan. One job per module:

* `missionplan.geo.errors`  - `GeoError`, the one-line error for any wrong geographic input.
* `missionplan.geo.camera`  - footprint side S = 2*H*tan(FOV/2) and cell = S/9; `Camera` from FOV or sensor.
* `missionplan.geo.frame`   - `GridFrame`: the grid laid in the area's UTM zone, grid <-> lat/lon, map meta.
* `missionplan.geo.readers` - area / obstacle / no-fly polygons from GeoJSON, KML, QGroundControl .plan;
                  building footprints (+ heights) from OSM .osm / .osm.pbf or GeoJSON.
* `missionplan.geo.area`    - `build_grid_map`: rasterise area, obstacles, buildings, no-fly into an `AreaRaster`
                  (plain arrays, wrapped into a GridMap by the planner).
* `missionplan.geo.cells`   - grid cells back on the Earth: merged lon/lat polygons, a GeoJSON feature.
* `missionplan.geo.geojson_layers` - GeoJSON layers for GIS files: RFC 7946 ring order (`rfc7946`), a layer's
                  geometry type and property types.
* `missionplan.geo.gpkg`    - `write_geopackage`: the layers as an OGC GeoPackage 1.3 (sqlite3, no GDAL).
* `missionplan.geo.kml`     - `write_kmz`: the layers as a KMZ for Google Earth (a folder per layer, heights).

Grid coordinates are float (row, col) whose integer values are cell centres; row 0 is the top
(north, before rotation) row; `rotation_deg` turns the grid clockwise from north.
"""

from .area import build_grid_map
from .camera import Camera, cell_size_m, footprint_side_m
from .errors import GeoError
from .frame import GridFrame, utm_epsg_for
from .readers import (Building, Feature, read_area, read_buildings, read_features, read_osm_buildings,
                      read_polygons)

__all__ = [
    "Building", "Camera", "Feature", "GeoError", "GridFrame", "build_grid_map", "cell_size_m",
    "footprint_side_m", "read_area", "read_buildings", "read_features", "read_osm_buildings", "read_polygons", "utm_epsg_for",
]
