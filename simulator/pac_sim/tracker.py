"""The overhead-camera tracker feed: one text line per gait cycle on a local TCP socket.

Line format (simulator/README.md): ``POSE <seq> <gait> <power_on> <x_cm> <y_cm> <h_deg>``.
A client first receives a ``#`` header line and a snapshot (gait -1) of the current pose.

A client may also place the robot, as an operator would before a run: it sends
``PLACE <x_cm> <y_cm> <h_deg> [<noise_seed>]`` and receives ``PLACED <x_cm> <y_cm> <h_deg>``,
the pose the tracker then sees (``ERROR <why>`` for a line it cannot parse).
"""

from __future__ import annotations

import socket
import threading

from pac_protocol.tracker_line import format_placed, format_pose_line, parse_place
from pac_sim.world import PoseSample, World

HEADER = "# pac-sim tracker 1: POSE seq gait cycles_since_power_on x_cm y_cm h_deg\n"


def format_pose(s: PoseSample) -> str:
    """The POSE line of a sample (the observed pose: a client never sees the true one)."""
    return format_pose_line(s.seq, s.gait, s.power_on, s.observed) + "\n"


class TrackerServer:
    """Publishes the world's poses to every connected client; never blocks the emulator long."""

    def __init__(self, world: World, host: str = "127.0.0.1", port: int = 0) -> None:
        self.world = world
        self._sock = socket.create_server((host, port))
        self.address = self._sock.getsockname()[:2]
        self._clients: list[socket.socket] = []
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._accept, name="pac-sim-tracker", daemon=True)
        world.observers.append(self.publish)
        self._thread.start()

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                conn, _ = self._sock.accept()
            except OSError:
                return
            conn.settimeout(1.0)
            # Snapshot, send and register under the publishing lock, so that no gait cycle
            # falls between the snapshot the client sees and the first POSE line it gets.
            with self._lock:
                try:
                    conn.sendall((HEADER + format_pose(self.world.snapshot())).encode())
                except OSError:
                    conn.close()
                    continue
                self._clients.append(conn)
            threading.Thread(target=self._serve, args=(conn,), name="pac-sim-tracker-client",
                             daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        """Answer the client's PLACE lines until it disconnects."""
        buf = b""
        while not self._closed.is_set():
            try:
                chunk = conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                return
            buf += chunk
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                line = raw.decode(errors="replace").strip()
                if not line:
                    continue
                try:
                    pose, seed = parse_place(line)
                    x, y, h = self.world.place(pose, seed)
                    reply = format_placed((x, y, h)) + "\n"
                except ValueError as e:
                    reply = f"ERROR {e}\n"
                with self._lock:
                    try:
                        conn.sendall(reply.encode())
                    except OSError:
                        return

    def publish(self, sample: PoseSample) -> None:
        data = format_pose(sample).encode()
        with self._lock:
            for c in list(self._clients):
                try:
                    c.sendall(data)
                except OSError:
                    self._clients.remove(c)
                    c.close()

    def close(self) -> None:
        self._closed.set()
        if self.publish in self.world.observers:
            self.world.observers.remove(self.publish)
        try:
            self._sock.shutdown(socket.SHUT_RDWR)  # wakes the blocked accept() on Linux
        except OSError:
            pass
        self._sock.close()
        with self._lock:
            for c in self._clients:
                c.close()
            self._clients.clear()
        self._thread.join(timeout=2)
