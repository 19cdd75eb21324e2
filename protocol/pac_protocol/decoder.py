"""Incremental frame decoder: bytes in any split, frames out; survives garbage (PROTOCOL.md 6).

A candidate frame that fails (LEN > 8 or a wrong CHK) costs only its first sync byte: the search
resumes one byte later, so a real frame that began inside a false candidate is still found. The
decoder never yields a frame whose check value is wrong.
"""

from __future__ import annotations

from pac_protocol.frame import HEADER, MAX_PAYLOAD, SYNC, Frame, check_value


class FrameDecoder:
    """Feed it bytes as they arrive; it returns the complete, checked frames they finish."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.skipped = 0  # bytes dropped while hunting for a sync
        self.bad_checks = 0  # candidates dropped for a wrong CHK
        self.bad_lengths = 0  # candidates dropped for LEN > MAX_PAYLOAD

    @property
    def pending(self) -> int:
        """Bytes held as the possible start of a frame."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray) -> list[Frame]:
        self._buf += data
        return self._drain()

    def expire(self) -> list[Frame]:
        """The line went quiet: a held partial frame will never complete. Drop it byte by byte
        and return any whole frames found inside it (e.g. a BOOT after a frame cut by a reset)."""
        out: list[Frame] = []
        while self._buf:
            del self._buf[:1]
            self.skipped += 1
            out += self._drain()
        return out

    def _drain(self) -> list[Frame]:
        out: list[Frame] = []
        buf = self._buf
        while buf:
            j = buf.find(SYNC)
            if j < 0:
                keep = 1 if buf[-1] == SYNC[0] else 0  # a trailing A5 may begin a sync
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if j:
                self.skipped += j
                del buf[:j]
            if len(buf) < HEADER:
                break
            n = buf[2]
            if n > MAX_PAYLOAD:
                self.bad_lengths += 1
                self.skipped += 1
                del buf[:1]
                continue
            size = HEADER + n + 1
            if len(buf) < size:
                break
            if check_value(buf[2 : size - 1]) == buf[size - 1]:
                out.append(Frame(buf[3], buf[4], bytes(buf[5 : size - 1])))
                del buf[:size]
            else:
                self.bad_checks += 1
                self.skipped += 1
                del buf[:1]
        return out
