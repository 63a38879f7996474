"""One connection per URL, shared by every vehicle on it: a reader thread and per-vehicle views.

A fleet usually reaches its ground station over one link: every vehicle sends to one UDP port
(`udpin:`), a SITL or mavlink-router TCP port serves one client, a telemetry radio is one serial
device. Opening one connection per vehicle then fails (the second socket cannot bind the port, the
second TCP client is refused, the device is busy). Here one link.connection.Link is opened per URL and:

- a reader thread takes every packet off it and routes it by source system id into that vehicle's
  queue (bounded: the oldest packets go first when a vehicle's thread does not keep up, counted);
- VehicleLink is one vehicle's view of the link, with what protocol code uses of a Link (recv with a
  deadline, mav for sending, command_long, reboots, heartbeat, the signing diagnosis), so a
  PymavlinkBackend, a MissionClient or a ParamClient runs over it unchanged, one thread per vehicle;
- sends go straight to the Link, which serialises them and, on udpin, sends each packet to the
  address its target vehicle's packets come from (link.connection);
- LinkPool opens the links of a fleet (`--connect URL` repeated, or `SYSID=URL`) and finds which link a
  system id is on (by its HEARTBEAT) when the URL was not given per system id.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

from missionplan.base.naming import Named

from ..errors import BridgeError, BridgeUsageError
from .connection import (COMMAND_TRIES, COMMAND_WAIT_S, GCS_COMPONENT_ID, GCS_SYSTEM_ID, Link, command_long, mavlink,
                   parse_sysid, parse_url)
from .signing import SigningKey

QUEUE_PACKETS = 4096  # per vehicle: a minute of a 25 Hz position stream plus the rest, at 10x speed-up
READ_SLICE_S = 0.2    # the reader looks at its stop flag at least this often


class SharedLink:
    """One Link read by one thread; vehicles registered with vehicle(sysid) get their packets queued."""

    def __init__(self, url: str, key: SigningKey | None = None, queue_packets: int = QUEUE_PACKETS,
                 source_system: int = GCS_SYSTEM_ID, source_component: int = GCS_COMPONENT_ID) -> None:
        self.link = Link(url, key, source_system, source_component)
        self.url = url
        self.queue_packets = queue_packets
        self._queues: dict[int, deque[Any]] = {}
        self._views: dict[int, VehicleLink] = {}
        self.dropped: dict[int, int] = {}  # packets a full queue let go, per system id
        self.heard: dict[tuple[int, int], float] = {}  # (system, component) of every non-GCS HEARTBEAT: when
        self._ready = threading.Condition()
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name=f"link-{url}", daemon=True)
        self._thread.start()

    # -- the reader
    def _read(self) -> None:
        link = self.link
        while not self._stop.is_set():
            try:
                msg = link.recv(time.monotonic() + READ_SLICE_S)
            except BaseException as err:  # noqa: BLE001 - the transport is gone: every view raises it
                with self._ready:
                    self._error = err
                    self._ready.notify_all()
                return
            if msg is None:
                continue
            src = (msg.get_srcSystem(), msg.get_srcComponent())
            with self._ready:
                if msg.get_type() == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS:
                    self.heard[src] = time.monotonic()
                queue = self._queues.get(src[0])
                if queue is None:
                    continue  # a system nobody asked for (yet): its next heartbeat will do
                if len(queue) == queue.maxlen:
                    self.dropped[src[0]] = self.dropped.get(src[0], 0) + 1
                queue.append(msg)
                self._ready.notify_all()

    def _next(self, sysid: int, deadline: float) -> Any | None:
        with self._ready:
            queue = self._queues[sysid]
            while not queue:
                if self._error is not None:
                    err = self._error
                    raise err if isinstance(err, BridgeError) else BridgeError(f"{self.url}: {err}")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._ready.wait(min(remaining, 0.5))
            return queue.popleft()

    # -- vehicles
    def vehicle(self, sysid: int) -> VehicleLink:
        """The view of system sysid (the same one each time); its packets are queued from now on."""
        with self._ready:
            if sysid not in self._views:
                self._queues[sysid] = deque(maxlen=self.queue_packets)
                self._views[sysid] = VehicleLink(self, sysid)
            return self._views[sysid]

    def heard_since(self, since: float) -> set[int]:
        """System ids whose HEARTBEAT this link carried since `since` (time.monotonic())."""
        with self._ready:
            return {s for (s, _), t in self.heard.items() if t >= since}

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.link.close()

    def __enter__(self) -> SharedLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class VehicleLink:
    """One vehicle's view of a SharedLink: reads only that vehicle's packets; sends on the shared Link.
    One thread per view (like a Link); close() lets the view go, the SharedLink stays open."""

    def __init__(self, shared: SharedLink, sysid: int) -> None:
        self.shared = shared
        self.sysid = sysid
        self.link = shared.link
        self.url, self.spec, self.key = shared.link.url, shared.link.spec, shared.link.key

    @property
    def mav(self) -> Any:
        return self.link.mav

    @property
    def reboots(self) -> dict[int, int]:
        return self.link.reboots  # kept by the reader thread (Link._track_boot)

    @property
    def received(self) -> int:
        return self.link.received

    @property
    def ack_rtt_s(self) -> dict[int, float]:
        return self.link.ack_rtt_s

    @property
    def dropped(self) -> int:
        """Packets of this vehicle lost because its queue was full."""
        return self.shared.dropped.get(self.sysid, 0)

    def recv(self, deadline: float) -> Any | None:
        """This vehicle's next packet, or None once time.monotonic() passes deadline; BridgeError when
        the link is gone."""
        return self.shared._next(self.sysid, deadline)

    def heartbeat(self, force: bool = False) -> None:
        self.link.heartbeat(force)  # the reader sends it at 1 Hz anyway; force it now if asked

    def command_long(self, sysid: int, command: int, params: list[float], deadline: float,
                     other: Callable[[Any], Any] | None = None, done: Callable[[], bool] | None = None,
                     tries: int = COMMAND_TRIES, wait_s: float = COMMAND_WAIT_S) -> int | None:
        return command_long(self, sysid, command, params, deadline, other, done, tries, wait_s)

    def heard_systems(self) -> set[tuple[int, int]]:
        """(system, component) of every vehicle heard on the shared link (for 'heard only ...')."""
        with self.shared._ready:
            return set(self.shared.heard)

    def signing_problem(self) -> str:
        return self.link.signing_problem()

    def signing_hint(self, sysid: int) -> str:
        return self.link.signing_hint(sysid)

    @property
    def bad_signatures(self) -> int:
        return self.link.bad_signatures

    @property
    def stale_signatures(self) -> int:
        return self.link.stale_signatures

    def close(self) -> None:
        """Nothing to close: the SharedLink's owner closes the connection."""


def parse_connects(values: Iterable[str], setting: str = "connect") -> tuple[dict[int, str], list[str]]:
    """`--connect` values: URL (vehicles found on it by heartbeat) or SYSID=URL / S1,S2=URL (those
    system ids are on that URL). Returns ({sysid: url}, [urls without system ids]); BridgeUsageError
    for a bad URL, a bad system id, or a system id given twice, naming `setting`."""
    by_sysid: dict[int, str] = {}
    pooled: list[str] = []
    for value in values:
        text = str(value).strip()
        head, sep, tail = text.partition("=")
        if sep and head.replace(",", "").replace(" ", "").isdigit():
            parse_url(tail, setting)
            for part in head.split(","):
                sysid = parse_sysid(part, setting)
                if sysid in by_sysid:
                    raise BridgeUsageError(Named("{name} {0}: system {1} is given a link twice", text, sysid,
                                                 name=setting))
                by_sysid[sysid] = tail.strip()
        else:
            parse_url(text, setting)
            if text not in pooled:
                pooled.append(text)
    if not by_sysid and not pooled:
        raise BridgeUsageError(Named("{name}: no connection given", name=setting))
    return by_sysid, pooled


class LinkPool:
    """The links of a fleet: one SharedLink per distinct URL, opened on first use, closed together; each
    signs with `key` (when given) and speaks as ground station (source_system, source_component)."""

    def __init__(self, connects: Iterable[str], key: SigningKey | None = None, source_system: int = GCS_SYSTEM_ID,
                 source_component: int = GCS_COMPONENT_ID) -> None:
        self.by_sysid, self.pooled = parse_connects(connects)
        self.key = key
        self.source = (source_system, source_component)
        self._links: dict[str, SharedLink] = {}
        self._lock = threading.Lock()

    def open_all(self) -> None:
        """Open every link now (a udpin port must listen before the vehicles' packets are lost)."""
        for url in dict.fromkeys([*self.by_sysid.values(), *self.pooled]):
            self.shared(url)

    def shared(self, url: str) -> SharedLink:
        with self._lock:
            if url not in self._links:
                self._links[url] = SharedLink(url, self.key, source_system=self.source[0],
                                              source_component=self.source[1])
            return self._links[url]

    def register(self, sysids: Iterable[int]) -> None:
        """Queue the packets of these system ids on every link they may be on, from now on."""
        for sysid in sysids:
            urls = [self.by_sysid[sysid]] if sysid in self.by_sysid else self.pooled
            for url in urls:
                self.shared(url).vehicle(sysid)

    def vehicle(self, sysid: int, timeout: float) -> VehicleLink:
        """The view of system sysid: on its own URL when given, on the only pooled URL, or else on the
        pooled link that carries its HEARTBEAT (BridgeError naming the URLs after `timeout`)."""
        if sysid in self.by_sysid:
            return self.shared(self.by_sysid[sysid]).vehicle(sysid)
        if not self.pooled:
            raise BridgeUsageError(f"--connect: no link for system {sysid} (give SYSID=URL or a URL for all)")
        if len(self.pooled) == 1:
            return self.shared(self.pooled[0]).vehicle(sysid)
        links = [self.shared(url) for url in self.pooled]
        for link in links:
            link.vehicle(sysid)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for link in links:
                if sysid in link.heard_since(0.0):
                    return link.vehicle(sysid)
            time.sleep(0.05)
        raise BridgeError(f"no heartbeat from system {sysid} on any of {', '.join(self.pooled)} within {timeout:g} s")

    def close(self) -> None:
        with self._lock:
            links, self._links = list(self._links.values()), {}
        for link in links:
            link.close()

    def __enter__(self) -> LinkPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
