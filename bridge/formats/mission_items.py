"""The mission model: what a vehicle is asked to fly, independent of files, links and planners.

Owns:
- MissionItem: one seq-free MAVLink mission item (command, frame, param1-4, x/lat, y/lon, z/alt,
  autocontinue). Coordinates are degrees for global frames, raw values otherwise.
- Mission: the items of one mission_type (mission, fence or rally) plus an optional home.
- WireItem: an item exactly as it travels in MISSION_ITEM_INT (seq, 1e7-scaled integers).
- The flavour rules that turn a Mission into wire items and back: ArduPilot keeps home as item 0 of
  the mission (an upload sends a placeholder there, a download returns the real home), PX4 does not;
  DO_JUMP targets are counted with home as item 0 on ArduPilot and without it on PX4.
The read-back rule (what a vehicle may legally change in what it stores, per flavour) builds on this
module: formats.readback.

Model convention for DO_JUMP: param1 is the 1-based number of the target in Mission.items (the same
number as QGroundControl's doJumpId for plain missions and as the line number in a .waypoints file).

Pure Python with no MAVLink library and no planner import, so every layer can use it.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, replace
from enum import Enum, IntEnum


class MissionType(IntEnum):
    """MAV_MISSION_TYPE."""

    MISSION = 0
    FENCE = 1
    RALLY = 2
    ALL = 255  # only for clear-all

    @property
    def label(self) -> str:
        return {0: "mission", 1: "fence", 2: "rally", 255: "all"}[int(self)]

    @classmethod
    def parse(cls, text: str) -> MissionType:
        names = {"mission": cls.MISSION, "fence": cls.FENCE, "rally": cls.RALLY, "all": cls.ALL}
        try:
            return names[text.strip().lower()]
        except KeyError:
            raise ValueError(f"unknown mission type {text!r} (mission, fence, rally or all)") from None


class Flavour(str, Enum):
    """Which mission conventions the vehicle follows, read from its HEARTBEAT `autopilot` field."""

    ARDUPILOT = "ardupilot"
    PX4 = "px4"
    GENERIC = "generic"  # any other autopilot: no home item, like PX4

    @classmethod
    def from_autopilot(cls, autopilot: int) -> Flavour:
        if autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA:
            return cls.ARDUPILOT
        if autopilot == MAV_AUTOPILOT_PX4:
            return cls.PX4
        return cls.GENERIC

    @property
    def autopilot(self) -> int:
        return {Flavour.ARDUPILOT: MAV_AUTOPILOT_ARDUPILOTMEGA, Flavour.PX4: MAV_AUTOPILOT_PX4,
                Flavour.GENERIC: MAV_AUTOPILOT_GENERIC}[self]

    def has_home_item(self, mission_type: int) -> bool:
        """ArduPilot stores home as item 0 of the mission (not of fence or rally lists)."""
        return self is Flavour.ARDUPILOT and mission_type == MissionType.MISSION


# MAVLink numbers for the modules that stay free of pymavlink (this one, formats.px4_rules, the mission files,
# sim.mock_flight and the planner): written down here and nowhere else, under their MAVLink names (CMD_
# for MAV_CMD_, FRAME_ for MAV_FRAME_); tests/test_mavlink_names.py checks them against pymavlink. A module
# that imports pymavlink takes its numbers from mavutil.mavlink instead.

# MAV_AUTOPILOT values used to tell flavours apart.
MAV_AUTOPILOT_GENERIC = 0
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_INVALID = 8
MAV_AUTOPILOT_PX4 = 12

MAV_TYPE_QUADROTOR = 2  # the vehicle type a .plan names

# MAV_MISSION_RESULT values of PX4's item checks.
MAV_MISSION_ACCEPTED = 0
MAV_MISSION_ERROR = 1
MAV_MISSION_UNSUPPORTED_FRAME = 2
MAV_MISSION_UNSUPPORTED = 3

# MAV_FRAME values a mission uses. The *_INT variants are deprecated aliases of the plain ones.
FRAME_GLOBAL = 0
FRAME_MISSION = 2
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_GLOBAL_INT = 5
FRAME_GLOBAL_RELATIVE_ALT_INT = 6
FRAME_GLOBAL_TERRAIN_ALT = 10
FRAME_GLOBAL_TERRAIN_ALT_INT = 11
GLOBAL_FRAMES = frozenset({FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_INT,
                           FRAME_GLOBAL_RELATIVE_ALT_INT, FRAME_GLOBAL_TERRAIN_ALT,
                           FRAME_GLOBAL_TERRAIN_ALT_INT})
_FRAME_ALIASES = {FRAME_GLOBAL_INT: FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT_INT: FRAME_GLOBAL_RELATIVE_ALT,
                  FRAME_GLOBAL_TERRAIN_ALT_INT: FRAME_GLOBAL_TERRAIN_ALT}

# MAV_CMD values the bridge needs to know by name.
CMD_NAV_WAYPOINT = 16
CMD_NAV_LOITER_UNLIM = 17
CMD_NAV_LOITER_TURNS = 18
CMD_NAV_LOITER_TIME = 19
CMD_NAV_RETURN_TO_LAUNCH = 20
CMD_NAV_LAND = 21
CMD_NAV_TAKEOFF = 22
CMD_NAV_LAND_LOCAL = 23
CMD_NAV_CONTINUE_AND_CHANGE_ALT = 30
CMD_NAV_LOITER_TO_ALT = 31
CMD_NAV_SPLINE_WAYPOINT = 82
CMD_NAV_VTOL_TAKEOFF = 84
CMD_NAV_VTOL_LAND = 85
CMD_NAV_DELAY = 93
CMD_NAV_PAYLOAD_PLACE = 94
CMD_NAV_LAST = 95  # not a command: navigation commands are numbered up to it, DO_ / CONDITION_ ones after
CMD_CONDITION_DELAY = 112
CMD_CONDITION_YAW = 115
CMD_DO_JUMP = 177
CMD_DO_CHANGE_SPEED = 178
CMD_DO_SET_HOME = 179
CMD_DO_LAND_START = 189
CMD_DO_REPOSITION = 192
CMD_DO_SET_ROI_LOCATION = 195
CMD_DO_SET_ROI = 201
CMD_DO_DIGICAM_CONTROL = 203
CMD_DO_MOUNT_CONTROL = 205
CMD_DO_SET_CAM_TRIGG_DIST = 206
CMD_DO_SET_CAM_TRIGG_INTERVAL = 214
CMD_DO_GIMBAL_MANAGER_PITCHYAW = 1000
CMD_IMAGE_START_CAPTURE = 2000
CMD_IMAGE_STOP_CAPTURE = 2001
CMD_DO_VTOL_TRANSITION = 3000
CMD_FENCE_POLYGON_VERTEX_INCLUSION = 5001  # MAV_CMD_NAV_FENCE_*
CMD_FENCE_POLYGON_VERTEX_EXCLUSION = 5002
CMD_FENCE_CIRCLE_INCLUSION = 5003
CMD_FENCE_CIRCLE_EXCLUSION = 5004
CMD_RALLY_POINT = 5100  # MAV_CMD_NAV_RALLY_POINT

SPEED_TYPE_GROUNDSPEED = 1  # DO_CHANGE_SPEED's param1 for a ground speed (SPEED_TYPE)
MAV_MOUNT_MODE_MAVLINK_TARGETING = 2  # DO_MOUNT_CONTROL's param7: point where the angles of the command say


def normalize_frame(frame: int) -> int:
    """Map deprecated *_INT frames to their plain number (ArduPilot answers 6 as 3, 5 as 0)."""
    return _FRAME_ALIASES.get(frame, frame)


def is_global(frame: int) -> bool:
    return frame in GLOBAL_FRAMES


def as_float32(value: float) -> float:
    """The value as a MAVLink float field carries it (and PX4 computes in: single precision)."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


@dataclass
class MissionItem:
    """One MAVLink mission item without its sequence number.

    x/y are latitude/longitude in degrees when the frame is global, raw numbers otherwise; z is the
    altitude in metres (relative to home in frame 3).
    """

    command: int
    frame: int = FRAME_GLOBAL_RELATIVE_ALT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    autocontinue: bool = True

    @property
    def lat(self) -> float:
        return self.x

    @property
    def lon(self) -> float:
        return self.y

    @property
    def alt(self) -> float:
        return self.z

    @property
    def params(self) -> tuple[float, float, float, float, float, float, float]:
        """The seven numbers QGroundControl writes as `params`."""
        return (self.param1, self.param2, self.param3, self.param4, self.x, self.y, self.z)


@dataclass
class Mission:
    """The items of one mission_type, plus the home position (lat, lon, alt AMSL) when known."""

    items: list[MissionItem] = field(default_factory=list)
    mission_type: MissionType = MissionType.MISSION
    home: tuple[float, float, float] | None = None

    def __len__(self) -> int:
        return len(self.items)


@dataclass(frozen=True)
class WireItem:
    """A mission item exactly as MISSION_ITEM_INT carries it."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int

    @classmethod
    def from_message(cls, msg: object) -> WireItem:
        """From a received MISSION_ITEM_INT (integers) or legacy MISSION_ITEM (float degrees)."""
        get = msg.__getattribute__
        x, y, frame = get("x"), get("y"), int(get("frame"))
        if isinstance(x, float) or isinstance(y, float):  # legacy float item: scale global coordinates
            x, y = encode_xy(frame, float(x)), encode_xy(frame, float(y))
        return cls(seq=int(get("seq")), frame=frame, command=int(get("command")), current=int(get("current")),
                   autocontinue=int(get("autocontinue")), param1=float(get("param1")),
                   param2=float(get("param2")), param3=float(get("param3")), param4=float(get("param4")),
                   x=int(x), y=int(y), z=float(get("z")), mission_type=int(getattr(msg, "mission_type", 0)))

    def fields(self) -> dict[str, float | int]:
        """Keyword arguments for pymavlink's mission_item_int_encode / send (without target ids)."""
        return {"seq": self.seq, "frame": self.frame, "command": self.command, "current": self.current,
                "autocontinue": self.autocontinue, "param1": self.param1, "param2": self.param2,
                "param3": self.param3, "param4": self.param4, "x": self.x, "y": self.y, "z": self.z,
                "mission_type": self.mission_type}


def encode_xy(frame: int, value: float) -> int:
    """x or y of MISSION_ITEM_INT: degrees * 1e7 rounded (not truncated) for global frames."""
    if is_global(frame):
        return int(round(value * 1e7))
    return int(round(value))


def decode_xy(frame: int, value: int) -> float:
    if is_global(frame):
        return value / 1e7
    return float(value)


def home_placeholder(home: tuple[float, float, float] | None, mission_type: int = MissionType.MISSION) -> WireItem:
    """Item 0 of an ArduPilot mission: the vehicle overwrites it with its real home."""
    lat, lon, alt = home if home is not None else (0.0, 0.0, 0.0)
    return WireItem(seq=0, frame=FRAME_GLOBAL, command=CMD_NAV_WAYPOINT, current=1, autocontinue=1,
                    param1=0.0, param2=0.0, param3=0.0, param4=0.0, x=encode_xy(FRAME_GLOBAL, lat),
                    y=encode_xy(FRAME_GLOBAL, lon), z=float(alt), mission_type=int(mission_type))


def to_wire(mission: Mission, flavour: Flavour) -> list[WireItem]:
    """The wire items to upload to a vehicle of this flavour (seq 0 is current, as MAVSDK demands)."""
    offset = 1 if flavour.has_home_item(mission.mission_type) else 0
    wire: list[WireItem] = []
    if offset:
        wire.append(home_placeholder(mission.home, mission.mission_type))
    for index, item in enumerate(mission.items):
        seq = index + offset
        param1 = item.param1
        if item.command == CMD_DO_JUMP:
            # Model: 1-based item number. ArduPilot counts home as 0 (same number), PX4 does not.
            param1 = float(int(round(item.param1)) - 1 + offset)
        wire.append(WireItem(seq=seq, frame=item.frame, command=item.command, current=1 if seq == 0 else 0,
                             autocontinue=1 if item.autocontinue else 0, param1=param1, param2=item.param2,
                             param3=item.param3, param4=item.param4, x=encode_xy(item.frame, item.x),
                             y=encode_xy(item.frame, item.y), z=float(item.z),
                             mission_type=int(mission.mission_type)))
    return wire


def from_wire(items: list[WireItem], flavour: Flavour, mission_type: int = MissionType.MISSION) -> Mission:
    """The Mission a vehicle of this flavour holds, given the items it returned (in seq order)."""
    items = sorted(items, key=lambda it: it.seq)
    home: tuple[float, float, float] | None = None
    offset = 0
    if flavour.has_home_item(mission_type) and items:
        first = items[0]
        home = (decode_xy(first.frame, first.x), decode_xy(first.frame, first.y), float(first.z))
        items = items[1:]
        offset = 1
    out: list[MissionItem] = []
    for it in items:
        param1 = it.param1
        if it.command == CMD_DO_JUMP:
            param1 = float(int(round(it.param1)) + 1 - offset)
        out.append(MissionItem(command=it.command, frame=it.frame, param1=param1, param2=it.param2,
                               param3=it.param3, param4=it.param4, x=decode_xy(it.frame, it.x),
                               y=decode_xy(it.frame, it.y), z=it.z, autocontinue=bool(it.autocontinue)))
    return Mission(items=out, mission_type=MissionType(mission_type), home=home)


def renumber(items: list[WireItem]) -> list[WireItem]:
    """Items with seq 0..n-1 in order and only seq 0 current."""
    return [replace(it, seq=i, current=1 if i == 0 else 0) for i, it in enumerate(items)]
