"""ArmLink for several threads (the ROS node's services, `uavarm link PORT shell`): one loop
reads the port and keeps the arm alive while other threads wait for the heartbeats that
confirm their commands."""
from __future__ import annotations

import threading

from .client import ArmLink, LinkError


class SharedLink(ArmLink):
    """ArmLink for several threads: only the loop reads the port (poll); command threads wait
    for the heartbeats it delivers. One re-entrant lock covers every read and write."""

    def __init__(self, port, baud: int = 115200, **kw):
        super().__init__(port, baud, **kw)
        self.cond = threading.Condition(threading.RLock())
        self.count = 0            # heartbeats received so far
        self.broken = None        # why the port failed, once it has
        self.pending = None       # the set position of a set_position command in flight

    @property
    def engaged(self) -> bool:
        return bool(self.heartbeats) and bool(self.heartbeats[-1]["engaged"])

    def send(self, name: str, **fields) -> None:
        with self.cond:
            if self.broken:
                raise LinkError(f"serial link lost: {self.broken}")
            if name == "set_position":
                self.pending = (fields["x"], fields["y"], fields["z"])
            super().send(name, **fields)

    def poll(self) -> list[dict]:
        with self.cond:
            new = super().poll()
            if new:
                self.count += len(new)
                self.cond.notify_all()
        return new

    def next_heartbeat(self, timeout: float | None = None) -> dict:
        timeout = self.silence if timeout is None else timeout
        with self.cond:
            start, since, end = self.count, self.counts(), self.clock() + timeout
            while not (self.count > start or self.broken):
                if self.clock() > end:
                    raise self.no_heartbeat(timeout, since)
                # woken by the loop's heartbeats; the clock (maybe not the wall's) says when to stop
                self.cond.wait(0.05)
            if self.broken:
                raise LinkError(f"serial link lost: {self.broken}")
            return self.heartbeats[-1]

    def set_position(self, x: float, y: float, z: float) -> dict:
        try:
            return super().set_position(x, y, z)
        finally:
            with self.cond:
                self.pending = None

    def keep_alive(self) -> None:
        """Repeat the set position: the one in flight if a set_position command waits for its
        confirmation (so a keep-alive never undoes it), else the latest heartbeat's."""
        with self.cond:
            if self.pending is not None:
                x, y, z = self.pending
            elif self.heartbeats:
                hb = self.heartbeats[-1]
                x, y, z = hb["set_x"], hb["set_y"], hb["set_z"]
            else:
                return
            ArmLink.send(self, "set_position", x=x, y=y, z=z)

    def fail(self, why: str) -> None:
        with self.cond:
            self.broken = why
            self.cond.notify_all()
            try:
                self.close()
            except Exception:
                pass
