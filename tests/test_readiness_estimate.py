"""missionplan.bridge.link.readiness's waits on the vehicle's own estimate before it flies: a position that stands still
(STEADY_M over STEADY_WINDOW_S) and, at arming, a vertical velocity at rest (QUIET_CLIMB_M_S). Both
from PX4 SIH: a take-off started while the position still converged sat armed on the ground for 220 s;
one armed while the vertical estimate moved was flown as a plain climb."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from missionplan.bridge.formats.mission_items import Flavour
from missionplan.bridge.link.readiness import QUIET_CLIMB_M_S, STEADY_M, STEADY_WINDOW_S, Vehicle, VehicleState


def _position(boot_s: float, east_m: float, climb_m_s: float = 0.0) -> SimpleNamespace:
    lon = 9.19 + east_m / (111_320.0 * np.cos(np.radians(45.4641)))
    return SimpleNamespace(get_type=lambda: "GLOBAL_POSITION_INT", time_boot_ms=int(boot_s * 1000),
                           lat=int(45.4641 * 1e7), lon=int(round(lon * 1e7)), vz=int(round(-climb_m_s * 100)),
                           get_srcSystem=lambda: 1)


def _steady_missing(state: VehicleState) -> list[str]:
    return [m for m in state.missing() if "position estimate" in m]


def test_a_vehicle_is_not_ready_while_its_position_estimate_still_converges() -> None:
    state = VehicleState(Flavour.PX4)
    assert _steady_missing(state) == [f"a position estimate ({STEADY_WINDOW_S:g} s of GLOBAL_POSITION_INT)"]
    # PX4 SIH right after "Ready for takeoff!": 2.5 m off, converging over about 6 s (the fleet test's uav3).
    for k in range(0, 61):
        boot = 35.0 + 0.1 * k
        state.take(_position(boot, 2.5 * np.exp(-(boot - 35.0) / 1.5)))
    # The last 5 s: from 1 s after the start (1.28 m off) to 6 s (0.05 m off).
    assert state.position_wander_m() == pytest.approx(2.5 * (np.exp(-1.0 / 1.5) - np.exp(-6.0 / 1.5)), abs=0.02)
    assert _steady_missing(state) == [f"a steady position estimate (moving more than {STEADY_M:g} m in "
                                      f"{STEADY_WINDOW_S:g} s)"]
    for k in range(61, 131):  # settled: SIH's GPS noise, decimetres
        boot = 35.0 + 0.1 * k
        state.take(_position(boot, 0.3 * np.sin(boot)))
    assert state.position_wander_m() < STEADY_M and _steady_missing(state) == []
    # A reboot restarts the vehicle's clock: its estimate has to prove itself again.
    state.take(_position(1.0, 0.0))
    assert state.position_wander_m() is None and _steady_missing(state)


def test_positions_of_zero_are_no_estimate() -> None:
    state = VehicleState(Flavour.ARDUPILOT)
    for k in range(80):
        state.take(SimpleNamespace(get_type=lambda: "GLOBAL_POSITION_INT", time_boot_ms=100 * k, lat=0, lon=0, vz=0))
    assert state.position_wander_m() is None


class _Clock:
    """missionplan.bridge.link.readiness's clock in these tests: time moves only when the link delivers a message, so
    the waits are measured exactly, whatever else the machine is doing."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


class _Link:
    """A link whose vehicle's vertical velocity estimate follows `climb(t)` (t: seconds since the start),
    one GLOBAL_POSITION_INT every 0.05 s of the clock; arming is accepted and its time kept."""

    def __init__(self, climb, clock: _Clock) -> None:
        self.clock, self.climb, self.armed_at, self.sent = clock, climb, None, 0
        self.start = clock.now

    def recv(self, until: float) -> SimpleNamespace | None:
        if self.clock.now >= until:
            return None
        self.clock.now = min(until, self.clock.now + 0.05)
        self.sent += 1
        return _position(40.0 + 0.05 * self.sent, 0.0, self.climb(self.clock.now - self.start))

    def command_long(self, sysid, command, params, deadline, other=None) -> int:
        self.armed_at = self.clock.now - self.start
        return 0


@pytest.fixture()
def clock(monkeypatch) -> _Clock:
    fake = _Clock()
    monkeypatch.setattr("missionplan.bridge.link.readiness.time", fake)
    return fake


def test_arming_waits_for_the_vertical_velocity_estimate_to_come_to_rest(clock: _Clock) -> None:
    # SIH's vertical estimate on the ground: 0.5 m/s, falling to rest over 0.6 s.
    link = _Link(lambda t: max(0.0, 0.5 - 0.8 * t), clock)
    said: list[str] = []
    vehicle = Vehicle(link, SimpleNamespace(sysid=1, flavour=Flavour.PX4), said.append)
    vehicle.listen(clock.now + 0.06)
    assert vehicle.arm(clock.now + 5.0) == (True, "")
    # Armed once the estimate is at rest: at the end of the 0.1 s listen that heard it settle.
    settled = (0.5 - QUIET_CLIMB_M_S) / 0.8
    assert settled <= link.armed_at <= settled + 0.1 + 1e-9
    assert any("vertical velocity estimate to settle" in line for line in said), said


def test_a_vertical_estimate_that_never_rests_delays_arming_only_to_the_bound(clock: _Clock) -> None:
    link = _Link(lambda t: 0.6, clock)
    vehicle = Vehicle(link, SimpleNamespace(sysid=1, flavour=Flavour.PX4))
    vehicle.listen(clock.now + 0.06)
    assert vehicle.wait_still(clock.now + 0.3) is False  # the deadline bounds it
    assert link.start + 0.36 - 1e-9 <= clock.now <= link.start + 0.36 + 1e-9
    assert vehicle.arm(clock.now + 0.3)[0] and link.armed_at == pytest.approx(0.66)
