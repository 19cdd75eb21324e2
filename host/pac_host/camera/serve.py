"""``pac-host camera serve``: the camera's poses as a stream for the ``tracker:`` observer, so
the camera can sit on another machine.

One client at a time. On connecting it gets a header line (:data:`ASK_HEADER`); for each gait
cycle it sends ``CYCLE <power_on> <index>`` (index 1 = a run's first gait cycle) and gets, from
the frames of the listening window that follows, ``POSE <seq> 32 <power_on> <x> <y> <h>`` (32:
the camera does not know the gait) or ``LOST <power_on> <why>``. A window that gives no pose
is looked at again, as the ``camera:`` observer does (``retries``; a live camera only).
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable

from pac_host.camera.observer import PoseFinder
from pac_host.observation import ObserverError
from pac_protocol.tracker_line import ASK_HEADER, format_pose_line

UNKNOWN_GAIT = 32
HEADER = (f"{ASK_HEADER} 1: send 'CYCLE power_on index'; answers 'POSE seq {UNKNOWN_GAIT} "
          "power_on x_cm y_cm h_deg' or 'LOST power_on why'\n")


class PoseServer:
    def __init__(self, source, finder: PoseFinder, host: str = "127.0.0.1", port: int = 0,
                 on_event: Callable[[str], None] | None = None) -> None:
        self.source, self.finder = source, finder
        self.on_event = on_event or (lambda _: None)
        self._sock = socket.create_server((host, port))
        self.address = self._sock.getsockname()[:2]
        self._closed = threading.Event()
        self.seq = 0

    def answer(self, line: str, last: dict) -> str:
        """The reply to one request line; ``last`` carries the previous pose per client."""
        parts = line.split()
        if len(parts) != 3 or parts[0] != "CYCLE" or not all(p.isdigit() for p in parts[1:]):
            return f"ERROR expected 'CYCLE power_on index', got {line.strip()[:60]!r}"
        power_on, index = int(parts[1]), int(parts[2])
        prev = last.get("pose") if index > 1 else None
        ref = prev[2] if prev is not None else self.finder.opts.heading0
        opts = self.finder.opts
        looks = 1 + (opts.retries if getattr(self.source, "now", False) else 0)
        why = "not looked"
        for _ in range(looks):
            try:
                frames = self.source.window(opts.frames, opts.window, power_on)
            except ObserverError as e:
                return f"LOST {power_on} {e}"
            pose, _, why = self.finder.in_window(frames, ref)
            if pose is not None:
                why = self.finder.impossible(pose, prev)
            if not why:
                break
        if why:
            last.pop("pose", None)
            return f"LOST {power_on} {why}"
        last["pose"] = pose
        self.seq += 1
        return format_pose_line(self.seq, UNKNOWN_GAIT, power_on, pose)

    def serve(self) -> None:
        """Serve clients one after another until :meth:`close`."""
        while not self._closed.is_set():
            try:
                conn, peer = self._sock.accept()
            except OSError:
                return
            self.on_event(f"client {peer[0]}:{peer[1]} connected")
            with conn:
                self._client(conn)
            self.on_event(f"client {peer[0]}:{peer[1]} gone")

    def _client(self, conn: socket.socket) -> None:
        last: dict = {}
        buf = b""
        try:
            conn.sendall(HEADER.encode())
            while not self._closed.is_set():
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    raw, buf = buf.split(b"\n", 1)
                    line = raw.decode(errors="replace").strip()
                    if line:
                        reply = self.answer(line, last)
                        self.on_event(reply)
                        conn.sendall((reply + "\n").encode())
        except OSError:
            return

    def close(self) -> None:
        self._closed.set()
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()
