"""How the command line says a library error: one line, each setting it names spelled as the option that
gives it. The library names settings by what they mean (missionplan.base.naming: `max_altitude`); the
option names live here, beside the parsers that define them, so a message reads `--max-altitude 90: below
the flight altitude 120 m` whichever layer found the fault."""

from __future__ import annotations

from missionplan.base.naming import Named, Setting

# Each setting a library error may name -> the option that gives it (tests/test_cli_errors.py checks that
# every setting the library names is here).
OPTIONS = {
    # plan: the area and the camera
    "area": "--area", "launch": "--launch", "altitude": "--altitude", "osm": "--osm",
    "height_field": "--height-field", "unknown_building_height": "--unknown-building-height", "fov": "--fov",
    "sensor_width": "--sensor-width", "sensor_height": "--sensor-height", "focal_length": "--focal-length",
    "rotation": "--rotation",
    # plan: the missions and their safety
    "uavs": "--uavs", "speed": "--speed", "overlap": "--overlap", "altitude_step": "--altitude-step",
    "min_separation": "--min-separation", "max_altitude": "--max-altitude", "clearance": "--clearance",
    "endurance": "--endurance", "reserve": "--reserve",
    # plan / replan: the folder and its page
    "out": "--out", "basemap": "--basemap",
    # replan: who flies it
    "drones": "--drones", "sysid": "--sysid",
    # the link: upload, download, clear, fly, mock
    "connect": "--connect", "compid": "--compid", "gcs_sysid": "--gcs-sysid", "gcs_compid": "--gcs-compid",
    "signing_key": "--signing-key", "backend": "--backend", "listen": "--listen", "speedup": "--speedup",
    "home": "--home",
    # fly
    "upload_with": "--upload-with", "on_abort": "--on-abort", "sortie": "--sortie",
}


def option(setting: Setting) -> str:
    """The option that gives `setting` (a setting with no entry: its key as an option, `--key-name`)."""
    return OPTIONS.get(setting.key, "--" + setting.key.replace("_", "-"))


def said(err: BaseException) -> str:
    """The error's one line as the command line says it."""
    message = err.args[0] if len(err.args) == 1 else None
    if isinstance(message, Named):
        return message.spelled(option)
    return str(err)
