"""Open the serial port a Stamp (or the emulator's pseudo-terminal) is on, with clear errors."""

from __future__ import annotations

import os
import stat

import serial

from pac_protocol.errors import PortError
from pac_protocol.timing import BAUD


def open_port(port: str, baud: int = BAUD, timeout: float = 0.05) -> serial.SerialBase:
    """Open ``port`` (a device path, or a pyserial URL such as ``loop://``) at 9600 8N1.

    DTR and RTS are deasserted before opening: on the BS2's programming port DTR resets the
    Stamp. Raises :class:`PortError` (exit 2) naming the port if it is missing or not serial.
    """
    if "://" in port:
        try:
            return serial.serial_for_url(port, baudrate=baud, timeout=timeout)
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
    return ser
