"""missionplan.bridge.formats.mission_items: wire conversion by flavour, DO_JUMP numbering, and the read-back
comparison."""

from __future__ import annotations

import math
from dataclasses import replace

from missionplan.bridge.formats.mission_items import (
    CMD_DO_JUMP,
    CMD_NAV_TAKEOFF,
    CMD_NAV_WAYPOINT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_RELATIVE_ALT_INT,
    FRAME_MISSION,
    Flavour,
    Mission,
    MissionItem,
    MissionType,
    encode_xy,
    from_wire,
    to_wire,
)
from missionplan.bridge.formats.readback import compare_wire


def _mission() -> Mission:
    return Mission(items=[MissionItem(CMD_NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, z=30.0),
                          MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, param2=2.0, param4=math.nan,
                                      x=45.12345678, y=7.65432109, z=30),
                          MissionItem(CMD_NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, x=45.2, y=7.7, z=35),
                          MissionItem(CMD_DO_JUMP, FRAME_MISSION, param1=2, param2=3)],
                   home=(45.0, 7.6, 240.0))


def test_ardupilot_gets_a_home_placeholder_and_keeps_jump_numbers() -> None:
    wire = to_wire(_mission(), Flavour.ARDUPILOT)
    assert len(wire) == 5
    assert [w.seq for w in wire] == [0, 1, 2, 3, 4]
    assert wire[0].command == CMD_NAV_WAYPOINT and wire[0].frame == 0 and wire[0].x == 450_000_000
    assert [w.current for w in wire] == [1, 0, 0, 0, 0]
    # Item 2 of the model is seq 2 on ArduPilot (home is 0): the jump target is unchanged.
    assert wire[4].command == CMD_DO_JUMP and wire[4].param1 == 2


def test_px4_has_no_home_item_and_shifts_jump_targets() -> None:
    wire = to_wire(_mission(), Flavour.PX4)
    assert len(wire) == 4
    assert wire[0].command == CMD_NAV_TAKEOFF and wire[0].current == 1
    assert wire[3].param1 == 1  # item 2 of the model is seq 1 on PX4


def test_coordinates_are_rounded_not_truncated() -> None:
    assert encode_xy(3, 45.12345678) == 451234568
    assert encode_xy(3, -7.00000009) == -70000001
    assert encode_xy(2, 3.6) == 4  # non-global frames carry plain numbers


def test_round_trip_through_the_wire_for_both_flavours() -> None:
    for flavour in (Flavour.ARDUPILOT, Flavour.PX4):
        mission = _mission()
        back = from_wire(to_wire(mission, flavour), flavour)
        assert len(back.items) == len(mission.items)
        for a, b in zip(mission.items, back.items):
            assert (a.command, a.frame, a.autocontinue) == (b.command, b.frame, b.autocontinue)
            assert math.isclose(a.x, b.x, abs_tol=1e-7) and math.isclose(a.y, b.y, abs_tol=1e-7)
            assert a.param1 == b.param1
        if flavour is Flavour.ARDUPILOT:
            assert back.home is not None and math.isclose(back.home[0], 45.0)


def test_compare_finds_each_kind_of_difference_and_skips_home() -> None:
    sent = to_wire(_mission(), Flavour.ARDUPILOT)
    assert compare_wire(sent, list(sent), skip_home=True) == []
    # ArduPilot replaces item 0 with its real home: not a difference.
    moved_home = [replace(sent[0], x=1, y=2, z=99.0)] + sent[1:]
    assert compare_wire(sent, moved_home, skip_home=True) == []
    assert compare_wire(sent, moved_home, skip_home=False)
    bad = list(sent)
    bad[2] = replace(bad[2], x=bad[2].x + 50)
    bad[3] = replace(bad[3], param2=1.0)
    problems = compare_wire(sent, bad, skip_home=True)
    assert any(p.startswith("item 2: x sent") for p in problems)
    assert any(p.startswith("item 3: param2 sent") for p in problems)
    assert compare_wire(sent, sent[:-1], skip_home=True)[0] == "the vehicle holds 4 items, 5 were sent"
    # NaN only equals NaN; a deprecated frame equals its plain number (ArduPilot answers 6 as 3).
    nan_lost = [replace(w, param4=0.0) if w.seq == 2 else w for w in sent]
    assert compare_wire(sent, nan_lost, skip_home=True)
    frame6 = [replace(w, frame=FRAME_GLOBAL_RELATIVE_ALT_INT) if w.frame == FRAME_GLOBAL_RELATIVE_ALT else w
              for w in sent]
    assert compare_wire(frame6, sent, skip_home=True) == []


def test_mission_types_parse_and_label() -> None:
    assert MissionType.parse("Fence") is MissionType.FENCE
    assert MissionType.RALLY.label == "rally"
    assert Flavour.from_autopilot(3) is Flavour.ARDUPILOT and Flavour.from_autopilot(12) is Flavour.PX4
    assert Flavour.from_autopilot(0) is Flavour.GENERIC
    assert not Flavour.ARDUPILOT.has_home_item(MissionType.FENCE)
