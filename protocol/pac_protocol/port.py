"""Open the serial port a Stamp (or the emulator's pseudo-terminal) is on, with clear errors.

The transport: a port that cannot be opened is a :class:`PortError` (the caller named a bad
port); once open, a port whose device goes away (a USB adapter pulled, the other end of a
pseudo-terminal closed) is a :class:`PortVanished` naming it, whatever pyserial or the operating
system raised (``OSError: [Errno 5] Input/output error`` from the bytes waiting, pyserial's
"device reports readiness to read but returned no data", a failed write).
"""

from __future__ import annotations

import os
import re
import stat

import serial

from pac_protocol.errors import PortError, PortVanished
from pac_protocol.timing import BAUD


def vanished_reason(error: OSError) -> str:
    """What the operating system said of a port that failed, without pyserial's wrapping.

    >>> vanished_reason(OSError(5, "Input/output error"))
    'Input/output error'
    >>> vanished_reason(serial.SerialException("read failed: [Errno 5] Input/output error"))
    'Input/output error'
    >>> vanished_reason(serial.SerialException("device reports readiness to read but returned "
    ...                                        "no data (device disconnected or multiple access "
    ...                                        "on port?)"))
    'device reports readiness to read but returned no data'
    """
    if error.strerror:
        return error.strerror
    text = str(error)
    m = re.search(r"\[Errno (\d+)\]|\((\d+), '", text)
    if m:
        return os.strerror(int(m.group(1) or m.group(2)))
    return text.split(" (")[0] or type(error).__name__


class SerialPort:
    """An open port (pyserial's ``Serial``, or what a URL names) whose failures after opening
    are :class:`PortVanished`, naming the port: a read, a write, the bytes waiting, a flush, a
    new timeout (pyserial reconfigures the device for it). Everything else is the pyserial
    object's, read and set through (the loader's DTR and break, say)."""

    def __init__(self, ser: serial.SerialBase, name: str) -> None:
        object.__setattr__(self, "_ser", ser)
        object.__setattr__(self, "_name", name)

    def _vanished(self, error: OSError) -> PortVanished:
        return PortVanished(f"the serial port {self._name} vanished ({vanished_reason(error)}; "
                            "a cable or USB adapter pulled out?)")

    def __getattr__(self, attr: str):
        return getattr(self._ser, attr)

    def __setattr__(self, attr: str, value) -> None:
        try:
            setattr(self._ser, attr, value)
        except OSError as e:
            if attr != "timeout":  # DTR or break on a port without them: the caller's to judge
                raise
            raise self._vanished(e) from e

    def read(self, size: int = 1) -> bytes:
        try:
            return self._ser.read(size)
        except OSError as e:
            raise self._vanished(e) from e

    def write(self, data: bytes) -> int | None:
        try:
            return self._ser.write(data)
        except OSError as e:
            raise self._vanished(e) from e

    @property
    def in_waiting(self) -> int:
        try:
            return self._ser.in_waiting
        except OSError as e:
            raise self._vanished(e) from e

    def flush(self) -> None:
        try:
            self._ser.flush()
        except OSError as e:
            raise self._vanished(e) from e

    def reset_input_buffer(self) -> None:
        try:
            self._ser.reset_input_buffer()
        except OSError as e:
            raise self._vanished(e) from e

    def close(self) -> None:
        """Close the port; one whose device is gone has nothing left to close."""
        try:
            self._ser.close()
        except OSError:
            pass

    def __enter__(self) -> SerialPort:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_port(port: str, baud: int = BAUD, timeout: float = 0.05) -> SerialPort:
    """Open ``port`` (a device path, or a pyserial URL such as ``loop://``) at 9600 8N1.

    DTR and RTS are deasserted before opening: on the BS2's programming port DTR resets the
    Stamp. Raises :class:`PortError` (exit 2) naming the port if it is missing or not serial;
    the port returned raises :class:`PortVanished` (exit 1) if it goes away later.
    """
    if "://" in port:
        try:
            return SerialPort(serial.serial_for_url(port, baudrate=baud, timeout=timeout), port)
        except (serial.SerialException, ValueError) as e:
            raise PortError(f"cannot open serial URL {port}: {e}") from None
    try:
        mode = os.stat(port).st_mode
    except FileNotFoundError:
        raise PortError(f"serial port {port} does not exist") from None
    except OSError as e:
        raise PortError(f"cannot access serial port {port}: {e.strerror}") from None
    if not stat.S_ISCHR(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "not a character device"
        raise PortError(f"{port} is not a serial device ({kind})")
    ser = serial.Serial()
    ser.port, ser.baudrate, ser.timeout = port, baud, timeout
    ser.bytesize, ser.parity, ser.stopbits = (
        serial.EIGHTBITS,
        serial.PARITY_NONE,
        serial.STOPBITS_ONE,
    )
    ser.dtr = False
    ser.rts = False
    try:
        ser.open()
    except serial.SerialException as e:
        msg = str(e)
        if "Inappropriate ioctl" in msg or "Errno 25" in msg:
            raise PortError(f"{port} is not a serial device (it is not a terminal)") from None
        raise PortError(f"cannot open serial port {port}: {msg}") from None
    return SerialPort(ser, port)
