"""The PX4 SIH fixture itself (sitl_tests/px4_sih.py): it boots where asked, logging off, boot
parameters applied, heard on its offboard port, with the system id and ground-station port asked for,
and leaves nothing running or on disk.
Skipped with a reason when ../shared/px4/bin/px4 is absent."""

from __future__ import annotations

import os

import pytest

from missionplan.bridge.link.connection import Link, mavlink, wait_vehicle
from missionplan.testing.loopback import free_udp_port
from missionplan.testing.px4_sih import PX4, e7, instance_free, px4_or_skip

pytestmark = pytest.mark.sitl  # starts a real autopilot: `pytest -m "not sitl"` leaves it out


def test_one_vehicle_boots_with_logging_off_and_its_boot_parameters(px4) -> None:
    home = (45.4641, 9.1891, 122.0)
    vehicle = px4(home=home, params={"TRIG_MODE": 4})
    folder, pid = vehicle.folder, vehicle.proc.pid
    with Link(vehicle.offboard_url) as link:
        info = wait_vehicle(link, vehicle.sysid, timeout=20.0)
    assert info.autopilot == mavlink.MAV_AUTOPILOT_PX4 and info.sysid == vehicle.instance + 1
    assert f"SIH_LOC_LAT0: curr: 454671160 -> new: {e7(home[0])}" in vehicle.log_text()
    assert "logger" not in vehicle.client("logger", "status").replace("[logger] not running", "")
    assert "mode : 4" in vehicle.client("camera_trigger", "status")  # started at boot by TRIG_MODE
    assert vehicle.log_files() == []  # the logger never started: no .ulg
    vehicle.stop()
    assert not folder.exists()
    assert not _alive(pid) and instance_free(vehicle.instance)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_restart_keeps_parameters_and_applies_new_boot_ones() -> None:
    px4_or_skip()
    with PX4() as vehicle:
        assert "camera_trigger" in vehicle.client("camera_trigger", "status") and \
            "not running" in vehicle.client("camera_trigger", "status")
        vehicle.client("param", "set", "MPC_XY_CRUISE", "7")
        vehicle.restart({"TRIG_MODE": 4})
        assert "mode : 4" in vehicle.client("camera_trigger", "status")
        assert "7.0" in vehicle.client("param", "show", "MPC_XY_CRUISE")


def test_a_fleet_vehicle_has_the_system_id_and_ground_station_port_asked_for(px4) -> None:
    port = free_udp_port()
    vehicle = px4(sysid=7, gcs_port=port)
    assert vehicle.gcs_url == f"udpin:127.0.0.1:{port}" and vehicle.offboard_url != vehicle.gcs_url
    with Link(vehicle.gcs_url) as link:  # its GCS link sends to our port, not to 14550
        info = wait_vehicle(link, 7, timeout=20.0)
    assert info.autopilot == mavlink.MAV_AUTOPILOT_PX4 and info.sysid == 7
