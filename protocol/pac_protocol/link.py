"""The host side of the exchange (PROTOCOL.md section 4) over any pyserial-like port.

:class:`StampLink` waits for the Stamp's READY, sends one request, reads the answer, and
retries on a NAK for a bad check, a lost request or a lost reply. Reports the Stamp sends
unasked (CYCLE, DONE, BOOT) are queued in order for the caller. It never prints.

Recovery comes in two layers (PROTOCOL.md 6): ``attempts`` retries of the identical request
(the Stamp's SEQ deduplication makes them safe), then up to ``resyncs`` resynchronisations: any
partial frame is forgotten, STATUS (itself retried) reads what the Stamp is doing, and the
request is tried again with its original SEQ. Only then :class:`NoAnswer` is raised. A line on
which nothing at all arrives is given up at once (a dead line, not a noisy one). Each retry and
resync is counted in :class:`LinkStats` and passed to ``on_event`` as a dict, for the caller's
log.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from pac_protocol.decoder import FrameDecoder
from pac_protocol.errors import (
    MessageError,
    Nacked,
    NoAnswer,
    StampReset,
    UsageError,
    VersionMismatch,
)
from pac_protocol.frame import Frame
from pac_protocol.messages import (
    MAX_GAIT,
    MAX_GENES,
    MAX_REPS,
    PROTOCOL_VERSION,
    Boot,
    Cycle,
    Done,
    Err,
    GeneReply,
    Hello,
    HelloReply,
    Load,
    Message,
    Nak,
    Read,
    Ready,
    Run,
    Status,
    StatusReply,
    Step,
    Stop,
    decode_message,
    reply_cmd,
)

READY_TIMEOUT_S = 2.0  # T_IDLE + the longest gait cycle (1.31 s, firmware) + margin
REPLY_TIMEOUT_S = 0.3
ATTEMPTS = 4
RESYNCS = 2  # rounds of STATUS + the same request again, after the attempts are used up
QUIET_S = 0.05  # a partial frame older than this is abandoned (PROTOCOL.md 6)
EVENT_TIMEOUT_S = 5.0  # longest wait for the next report of a run
HINTS = {
    Err.BUSY: " (a run is in progress: send STOP first)",
    Err.EMPTY: " (no runnable turn cycle is stored: LOAD one first)",
}


class SerialLike(Protocol):
    timeout: float | None

    def read(self, size: int = 1) -> bytes: ...
    def write(self, data: bytes) -> int | None: ...
    @property
    def in_waiting(self) -> int: ...


@dataclass
class LinkStats:
    requests: int = 0
    sends: int = 0  # requests + retries
    retries: int = 0
    echoes: int = 0  # request-direction frames received (pin-16 echo)
    undecodable: int = 0
    boots: int = 0
    resyncs: int = 0


class _Retry(Exception):
    def __init__(self, why: str, ready_now: bool = False) -> None:
        super().__init__(why)
        self.ready_now = ready_now


class StampLink:
    """One conversation with a Stamp. ``port`` needs ``read``, ``write``, ``in_waiting`` and a
    writable ``timeout`` (pyserial's ``Serial`` or the emulator's pseudo-terminal opened by it)."""

    def __init__(
        self,
        port: SerialLike,
        *,
        name: str | None = None,
        ready_timeout: float = READY_TIMEOUT_S,
        reply_timeout: float = REPLY_TIMEOUT_S,
        attempts: int = ATTEMPTS,
        resyncs: int = RESYNCS,
        quiet_s: float = QUIET_S,
        clock: Callable[[], float] = time.monotonic,
        on_event: Callable[[dict], None] | None = None,
    ) -> None:
        self.port = port
        self.name = name or str(getattr(port, "port", None) or getattr(port, "name", "port"))
        self.ready_timeout = ready_timeout
        self.reply_timeout = reply_timeout
        self.attempts = attempts
        self.resyncs = resyncs
        self.on_event = on_event  # called with each retry and resync (a dict), for a log
        self.last_status: StatusReply | None = None  # what the last resync read
        self.quiet_s = quiet_s
        self.clock = clock
        self.decoder = FrameDecoder()
        self.events: deque[Message] = deque()
        self.stats = LinkStats()
        self.seen: deque[str] = deque(maxlen=4)  # recent frames, for error messages
        self.rx_bytes = 0
        self.last_seq = -1
        self.last_round_trip_s = float("nan")  # request written -> reply decoded, last success
        self._frames: deque[Frame] = deque()
        self._last_rx = clock()
        self._seq = 0
        self._acted_seq = 0

    # ---- reading ------------------------------------------------------------------------------

    def _next_frame(self, deadline: float) -> Frame | None:
        """The next reply-direction frame, or None at the deadline. Echoes are counted, skipped."""
        while True:
            while self._frames:
                f = self._frames.popleft()
                if not f.is_reply:
                    self.stats.echoes += 1
                    continue
                return f
            now = self.clock()
            if now >= deadline:
                return None
            self.port.timeout = max(0.001, min(deadline - now, self.quiet_s))
            data = self.port.read(max(1, self.port.in_waiting))
            now = self.clock()
            if data:
                self.rx_bytes += len(data)
                self._last_rx = now
                self._frames.extend(self.decoder.feed(data))
            elif self.decoder.pending and now - self._last_rx >= self.quiet_s:
                self._frames.extend(self.decoder.expire())

    def _fresh(self) -> bool:
        """True if nothing has arrived after the frame just taken (the READY rule of 4.1)."""
        return not self._frames and not self.decoder.pending and not self.port.in_waiting

    def _next_message(self, deadline: float) -> Message | None:
        """The next decodable reply-direction message; its SEQ is left in ``self.last_seq``."""
        while True:
            f = self._next_frame(deadline)
            if f is None:
                return None
            try:
                m = decode_message(f)
            except MessageError:
                self.stats.undecodable += 1
                self.seen.append(f"undecodable frame {f.hex()}")
                continue
            self.seen.append(m.describe())
            self.last_seq = f.seq
            return m

    def _note_report(self, m: Message) -> None:
        if isinstance(m, Boot):
            self.stats.boots += 1
        self.events.append(m)

    def _wait_ready(self, deadline: float) -> Ready | None:
        while True:
            m = self._next_message(deadline)
            if m is None:
                return None
            if isinstance(m, Ready):
                if self._fresh():
                    return m
            elif isinstance(m, Boot | Cycle | Done):
                self._note_report(m)
            # anything else: a stale reply to an earlier attempt; ignore

    # ---- the exchange -------------------------------------------------------------------------

    def _next_seq(self) -> int:
        """1..255, never the SEQ of the last LOAD/RUN/STEP the Stamp executed (PROTOCOL.md 4.2)."""
        self._seq = self._seq % 255 + 1
        if self._seq == self._acted_seq:
            self._seq = self._seq % 255 + 1
        return self._seq

    def _heard(self) -> str:
        if self.seen:
            return "; ".join(self.seen)
        if self.rx_bytes:
            return f"{self.rx_bytes} bytes but no valid frame (wrong baud rate or not a ServoBot?)"
        return "nothing"

    def _event(self, doc: dict) -> None:
        if self.on_event is not None:
            self.on_event(doc)

    def request(self, msg: Message) -> Message:
        """Send one request and return the Stamp's reply, retrying as PROTOCOL.md 4.2 says,
        then resynchronising (module docstring) before giving up."""
        seq = self._next_seq()
        data = msg.encode(seq)
        self.stats.requests += 1
        why = ""
        for rnd in range(self.resyncs + 1):
            if rnd and not self._resync(msg, why):
                why += "; STATUS unanswered too"
                continue
            try:
                reply = self._exchange(msg, seq, data, first=rnd == 0)
            except _Retry as r:
                why = str(r)
                continue
            if isinstance(msg, Hello):
                self._acted_seq = 0
            elif isinstance(msg, Load | Run | Step):
                self._acted_seq = seq
            return reply
        raise NoAnswer(
            f"{self.name}: no answer to {msg.describe()} after {self.attempts} attempts and "
            f"{self.resyncs} resynchronisation(s) (expected {reply_cmd(msg.CMD):02X} with SEQ "
            f"{seq}; last: {why}; received {self._heard()})"
        )

    def _exchange(self, msg: Message, seq: int, data: bytes, first: bool) -> Message:
        """Up to ``attempts`` sends of ``data``; raises _Retry with the last reason."""
        ready_now = False
        why = ""
        for attempt in range(self.attempts):
            if attempt or not first:
                self.stats.retries += 1
                self._event({"type": "retry", "request": msg.describe(), "seq": seq,
                             "why": why})
            if not ready_now:
                rx = self.rx_bytes
                if self._wait_ready(self.clock() + self.ready_timeout) is None:
                    if self.rx_bytes == rx:  # not a byte: a dead line, not a noisy one
                        raise NoAnswer(
                            f"{self.name}: no READY from the Stamp within "
                            f"{self.ready_timeout:g} s (expected frames starting A5 5A; "
                            f"received {self._heard()})"
                        )
                    why = f"no fresh READY within {self.ready_timeout:g} s"
                    continue
            self.port.write(data)
            self.stats.sends += 1
            t0 = self.clock()
            try:
                reply = self._await_reply(msg, seq)
            except _Retry as r:
                why, ready_now = str(r), r.ready_now
                continue
            self.last_round_trip_s = self.clock() - t0
            return reply
        raise _Retry(why)

    def _resync(self, msg: Message, why: str) -> bool:
        """Forget any partial frame, then ask STATUS (retried, never resynchronised itself):
        True if the Stamp answered, what it is doing then in :attr:`last_status`. HELLO is not
        used here: it clears the Stamp's lastSeq, which a pending LOAD, RUN or STEP relies on."""
        self.stats.resyncs += 1
        self.decoder = FrameDecoder()
        self._frames.clear()
        seq = self._next_seq()
        status = Status()
        try:
            st = self._exchange(status, seq, status.encode(seq), first=True)
        except _Retry as r:
            self._event({"type": "resync", "request": msg.describe(), "why": why,
                         "answered": False, "status_why": str(r)})
            return False
        assert isinstance(st, StatusReply)
        self.last_status = st
        self._event({"type": "resync", "request": msg.describe(), "why": why, "answered": True,
                     "state": int(st.state), "done": st.done, "power_on": st.power_on})
        return True

    def _await_reply(self, msg: Message, seq: int) -> Message:
        deadline = self.clock() + self.reply_timeout
        want = reply_cmd(msg.CMD)
        while True:
            m = self._next_message(deadline)
            if m is None:
                raise _Retry(f"no reply within {self.reply_timeout:g} s")
            if isinstance(m, Nak):
                if m.error == Err.BAD_CHECK:
                    raise _Retry("NAK bad check")
                if self.last_seq == seq:
                    raise Nacked(
                        f"{self.name}: the Stamp refused {msg.describe()}: {m.error_name()}"
                        + HINTS.get(m.error, ""),
                        m.command,
                        m.error,
                    )
            elif isinstance(m, Ready):
                raise _Retry("the Stamp was listening again before it answered", self._fresh())
            elif isinstance(m, Boot | Cycle | Done):
                self._note_report(m)
            elif int(m.CMD) == want and self.last_seq == seq:
                return m

    # ---- events -------------------------------------------------------------------------------

    @property
    def last_heard(self) -> float:
        """When the last byte from the Stamp was read (on :attr:`clock`; the link's creation if
        none yet)."""
        return self._last_rx

    def next_event(self, timeout: float = EVENT_TIMEOUT_S,
                   since: float | None = None) -> Message | None:
        """The next report (CYCLE, DONE, BOOT), queued or read within ``timeout``, else None.
        ``since`` (e.g. :attr:`last_heard`): count the ``timeout`` from then, not from now, so
        time the caller spent on the last report does not lengthen a silence; bytes already
        waiting are read all the same."""
        if self.events:
            return self.events.popleft()
        now = self.clock()
        deadline = now + timeout if since is None else max(since + timeout, now + self.quiet_s)
        while True:
            m = self._next_message(deadline)
            if m is None:
                return None
            if isinstance(m, Boot | Cycle | Done):
                if isinstance(m, Boot):
                    self.stats.boots += 1
                return m

    def wait_done(
        self, timeout: float = EVENT_TIMEOUT_S, on_cycle: Callable[[Cycle], None] | None = None
    ) -> tuple[list[Cycle], Done]:
        """Collect CYCLE reports (each also passed to ``on_cycle``) until DONE. Raises
        StampReset on BOOT, NoAnswer if no report comes for ``timeout`` seconds."""
        cycles: list[Cycle] = []
        while True:
            ev = self.next_event(timeout)
            if ev is None:
                raise NoAnswer(
                    f"{self.name}: no report for {timeout:g} s during a run "
                    f"({len(cycles)} gait cycles reported; received {self._heard()})"
                )
            if isinstance(ev, Boot):
                raise StampReset(
                    f"{self.name}: the Stamp reset during a run after {len(cycles)} reported "
                    "gait cycles"
                )
            if isinstance(ev, Cycle):
                cycles.append(ev)
                if on_cycle is not None:
                    on_cycle(ev)
            elif isinstance(ev, Done):
                return cycles, ev

    # ---- commands -----------------------------------------------------------------------------

    def hello(self) -> HelloReply:
        """HELLO; checks the protocol version (VersionMismatch names port, expected, received)."""
        r = self.request(Hello())
        assert isinstance(r, HelloReply)
        # a BOOT heard before HELLO is the power-on this session starts from, not news
        self.events = deque(e for e in self.events if not isinstance(e, Boot))
        if r.protocol != PROTOCOL_VERSION:
            raise VersionMismatch(
                f"{self.name}: expected protocol version {PROTOCOL_VERSION}, the Stamp speaks "
                f"version {r.protocol} (firmware {r.firmware})"
            )
        return r

    def status(self) -> StatusReply:
        r = self.request(Status())
        assert isinstance(r, StatusReply)
        return r

    def load(self, genes: list[tuple[int, int]]) -> None:
        """Store a turn cycle of 1..9 (gait id, repetitions) genes, one LOAD per gene, in order."""
        check_genes(genes)
        for i, (g, r) in enumerate(genes):
            self.request(Load(len(genes), i, g, r))

    def read_gene(self, index: int) -> GeneReply:
        r = self.request(Read(index))
        assert isinstance(r, GeneReply)
        return r

    def run(self, cycles: int) -> None:
        """Start the stored turn cycle for ``cycles`` gait cycles; reports follow as events
        (reports still queued from before belong to an earlier run and are dropped)."""
        self.events.clear()
        self.request(Run(cycles))

    def step(self, gait: int, reps: int) -> None:
        """Start ``reps`` gait cycles of ``gait``; reports follow as events (older ones dropped)."""
        self.events.clear()
        self.request(Step(gait, reps))

    def stop(self) -> None:
        self.request(Stop())


def check_genes(genes: list[tuple[int, int]]) -> None:
    """Raise :class:`UsageError` unless ``genes`` is a turn cycle the Stamp accepts."""
    if not 1 <= len(genes) <= MAX_GENES:
        raise UsageError(f"a turn cycle has 1..{MAX_GENES} genes, got {len(genes)}")
    for i, (g, r) in enumerate(genes):
        if not (0 <= g <= MAX_GAIT and 0 <= r <= MAX_REPS):
            raise UsageError(
                f"gene {i}: gait id {g} must be 0..{MAX_GAIT}, repetitions {r} 0..{MAX_REPS}"
            )
