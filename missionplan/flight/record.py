"""What a flight learned about one vehicle (DroneRecord), and the one way it is written down.

fly's per-drone thread changes a record only through its `set` / `add_*` methods; each change also
goes to the record's `sink` (the flight journal, journal.py) as it happens, so that a crash of the
ground station loses at most what the journal had not committed yet. Replaying the journal calls the
same methods without a sink and gives the same record back: flight.json is judged from that replay.

Times are seconds of our wall clock (time.time()): a record outlives the process that began it (a
`fly --resume` continues it), and only differences of these times are ever used. The vehicle's own
clock (time_boot_ms) travels in the samples.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

# (wall time, lat, lon, up m, ground speed m/s, the vehicle's time since boot s, climb rate m/s)
Sample = tuple[float, float, float, float, float, float, float]
Sink = Callable[[str, tuple[Any, ...]], None]
FACTS = ("planned_photos", "uploaded", "arming", "started", "finished", "held_after_flight", "mission_state", "current",
         "captures", "failed_captures", "wire", "params", "flavour", "t_start", "t_end", "ended_early", "last_position")
GIMBAL_CHANGE_DEG = 0.5  # a gimbal report this close to the last one kept is not journaled again
PHOTO_SOURCES = ("camera", "log")  # a report over the link; the vehicle's own log, read after the flight


@dataclass
class DroneRecord:
    """What the ground station learned about one vehicle during a flight (times: our wall clock)."""

    id: int
    planned_photos: int = 0
    uploaded: bool = False
    # When fly was about to arm it (our clock): committed to the journal before the arm command is sent,
    # so that `fly --resume` finds every vehicle fly may have armed, started or not.
    arming: float | None = None
    started: bool = False
    finished: bool = False
    held_after_flight: bool | None = None
    mission_state: int = 0
    current: int = 0
    captures: int = 0  # photos the camera says it took (completed_captures / highest img_idx + 1)
    failed_captures: int = 0  # a MAVLink camera's CAMERA_IMAGE_CAPTURED with capture_result 0: no photo
    wire: list[Any] = field(default_factory=list)  # the mission as uploaded (mission_items.WireItem)
    reached: list[tuple[float, int]] = field(default_factory=list)  # arrival time, seq
    landed: list[tuple[float, int]] = field(default_factory=list)  # EXTENDED_SYS_STATE landed state, at each change
    events: list[tuple[float, str]] = field(default_factory=list)  # mode, arming, landed state, STATUSTEXT, alerts
    samples: list[Sample] = field(default_factory=list)
    camera: dict[int, tuple[float, float, float, float]] = field(default_factory=dict)  # img_idx -> t, lat, lon, up
    amsl: dict[int, float] = field(default_factory=dict)  # img_idx -> altitude above mean sea level, m, where reported
    photo_source: dict[int, str] = field(default_factory=dict)  # img_idx -> "camera" or "log"
    attitude: dict[int, tuple[float, float, float]] = field(default_factory=dict)  # img_idx -> roll, pitch, yaw deg
    # A MAVLink camera's photos (plan --capture camera*): img_idx (its image_index) -> the file_url it named ("" for
    # none); the autopilot's and the log's photos have none. And the indices it failed (live only).
    files: dict[int, str] = field(default_factory=dict)
    failed_indices: set[int] = field(default_factory=set)
    # What the vehicle reported of its camera gimbal, at each change: (wall time, pitch deg, roll deg).
    gimbal: list[tuple[float, float, float]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)  # navigation parameters the vehicle reported
    flavour: str = ""  # the autopilot's conventions (a mission_items.Flavour value): which flight model times it
    t_start: float | None = None
    t_end: float | None = None
    ended_early: str = ""  # why the vehicle ended its mission before its last item (a failsafe, a landing)
    last_position: list[float] | None = None  # lat, lon, up m, wall time of the last sample
    last_heard: float = 0.0  # not journaled: the live follower's own bookkeeping
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    sink: Sink | None = field(default=None, repr=False, compare=False)

    def _emit(self, kind: str, *row: Any) -> None:
        if self.sink is not None:
            self.sink(kind, row)

    def set(self, **facts: Any) -> None:
        """Change facts (FACTS) of the record; each is journaled as its latest value."""
        for name, value in facts.items():
            if name not in FACTS:
                raise AttributeError(f"{name} is not a journaled fact of a drone record")
            if getattr(self, name) != value:
                setattr(self, name, value)
                self._emit("fact", name, value)

    def add_sample(self, sample: Sample) -> None:
        self.samples.append(sample)
        self._emit("sample", *sample)

    def add_photo(self, idx: int, t: float, lat: float, lon: float, up: float, source: str = "camera",
                  attitude: tuple[float, float, float] | None = None, amsl: float | None = None,
                  file_url: str | None = None) -> bool:
        """A photo and where it was taken; the first word about an index stands (a report repeated over
        the link, or the log's copy of a photo already reported). Whether it was new. file_url: a MAVLink
        camera's record names its file ("" when it names none); None for any other report."""
        if idx in self.camera:
            return False
        self.camera[idx] = (t, lat, lon, up)
        self.photo_source[idx] = source
        if attitude is not None:
            self.attitude[idx] = attitude
        if amsl is not None:
            self.amsl[idx] = amsl
        if file_url is not None:
            self.files[idx] = file_url
        roll, pitch, yaw = attitude if attitude is not None else (None, None, None)
        self._emit("photo", idx, t, lat, lon, up, source, roll, pitch, yaw, amsl, file_url)
        return True

    def add_reached(self, t: float, seq: int) -> None:
        if not self.reached or self.reached[-1][1] != seq:  # PX4 repeats its last one every second
            self.reached.append((t, seq))
            self._emit("reached", t, seq)

    def add_gimbal(self, t: float, pitch: float, roll: float) -> None:
        """The gimbal's reported pitch and roll (degrees), kept when they changed by GIMBAL_CHANGE_DEG or more."""
        if self.gimbal and abs(self.gimbal[-1][1] - pitch) < GIMBAL_CHANGE_DEG \
                and abs(self.gimbal[-1][2] - roll) < GIMBAL_CHANGE_DEG:
            return
        self.gimbal.append((t, pitch, roll))
        self._emit("gimbal", t, pitch, roll)

    def gimbal_at(self, t: float) -> tuple[float, float] | None:
        """(pitch, roll) the gimbal last reported at or before `t`, or None when it had reported none."""
        before = [(pitch, roll) for when, pitch, roll in self.gimbal if when <= t]
        return before[-1] if before else None

    def add_landed(self, t: float, state: int) -> None:
        self.landed.append((t, state))
        self._emit("landed", t, state)

    def add_event(self, t: float, text: str) -> None:
        self.events.append((t, text))
        self._emit("event", t, text)

    def add_problem(self, text: str) -> None:
        self.problems.append(text)
        self._emit("problem", text)

    def add_note(self, text: str) -> None:
        self.notes.append(text)
        self._emit("note", text)

    def replay(self, kind: str, row: tuple[Any, ...]) -> None:
        """Apply one journaled change (what _emit wrote) to this record, without journaling it again."""
        sink, self.sink = self.sink, None
        try:
            if kind == "fact":
                self.set(**{row[0]: row[1]})
            elif kind == "sample":
                self.add_sample(tuple(row))  # type: ignore[arg-type]
            elif kind == "photo":
                # amsl, then file_url: journals from before them lack them
                idx, t, lat, lon, up, source, roll, pitch, yaw, *rest = row
                attitude = None if roll is None else (roll, pitch, yaw)
                self.add_photo(int(idx), t, lat, lon, up, source, attitude, rest[0] if rest else None,
                               rest[1] if len(rest) > 1 else None)
            elif kind == "reached":
                self.add_reached(row[0], int(row[1]))
            elif kind == "landed":
                self.add_landed(row[0], int(row[1]))
            elif kind == "gimbal":
                self.add_gimbal(row[0], row[1], row[2])
            elif kind == "event":
                self.add_event(row[0], row[1])
            elif kind == "problem":
                self.add_problem(row[0])
            elif kind == "note":
                self.add_note(row[0])
            else:
                raise ValueError(f"unknown journal entry {kind!r}")
        finally:
            self.sink = sink
