"""missionplan.geo: world <-> grid (camera footprint, projection, rasterising, area files, GIS files).

Installed as missionplan.geo from the repository's geo/ folder. May import: missionplan.base (atomic writes),
nothing else from missionplan. One job per module:

* `missionplan.geo.errors`  - `GeoError`, the one-line error for any wrong geographic input.
* `missionplan.geo.camera`  - footprint side S = 2*H*tan(FOV/2) and cell = S/9; `Camera` from FOV or sensor.
* `missionplan.geo.frame`   - `GridFrame`: the grid laid in the area's UTM zone, grid <-> lat/lon, map meta.
* `missionplan.geo.georeference` - `Georeference`: a grid's frame, flight altitude and camera as one typed value,
                  written to and read from a map's header lines and report.json's `georeference`.
* `missionplan.geo.readers` - area / obstacle / no-fly polygons and building footprints from any file a crew
                  brings, chosen by extension (`FILE:LAYER` for a layer); each format has its module:
                  `geojson_file` (GeoJSON), `kml_file` (KML, KMZ), `plan_file` (QGroundControl .plan),
                  `ogr_files` (GeoPackage, Shapefile, FlatGeobuf, GML through GDAL / pyogrio), `osm` (OSM
                  .osm / .osm.pbf through pyosmium). Beside them: `shapes` (the checks every polygon
                  passes), `crs` (reprojection to WGS84 lon/lat), `heights` (a footprint's height from its
                  attributes), `guards` (zip and XML hazards, before a parser sees the file) and
                  `sources` (Feature, Building, and `SourceFile`: how a file was read, what it left out).
* `missionplan.geo.area`    - `build_grid_map`: rasterise area, obstacles, buildings, no-fly into an `AreaRaster`
                  (plain arrays, wrapped into a GridMap by the planner).
* `missionplan.geo.dem`     - `read_ground`: the window of a crew's DEM files (GeoTIFF, SRTM .hgt, any GDAL
                  raster; rasterio, the `terrain` extra) around an area; `Ground.height_amsl` at WGS84 points.
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
from .georeference import Georeference
from .readers import (Building, Feature, read_area, read_area_file, read_building_file, read_buildings,
                      read_features, read_obstacle_file, read_osm_buildings, read_polygons)
from .sources import Omission, SourceFile

__all__ = [
    "Building", "Camera", "Feature", "GeoError", "Georeference", "GridFrame", "Omission", "SourceFile", "build_grid_map",
    "cell_size_m", "footprint_side_m", "read_area", "read_area_file", "read_building_file", "read_buildings", "read_features",
    "read_obstacle_file", "read_osm_buildings", "read_polygons", "utm_epsg_for",
]
