"""Flash the robot and check the result: the BS2 download, then HELLO from the new firmware.

Sits between the CLI and the loader: opens the port (DTR deasserted, as the protocol requires),
runs :class:`pac_host.stamp_loader.StampLoader`, and, when the image is the ServoBot firmware,
asks the freshly started program HELLO and compares the firmware version it reports with the
image's. Nothing here prints; progress goes to the callback.
"""

from __future__ import annotations

from dataclasses import dataclass

from pac_host.stamp_image import StampImage
from pac_host.stamp_loader import FlashError, FlashReport, Progress, StampLoader
from pac_protocol.link import StampLink
from pac_protocol.port import open_port


class VerifyError(FlashError):
    """The download completed but the robot does not run the image's firmware."""


@dataclass(frozen=True)
class FlashOutcome:
    report: FlashReport
    image_version: int | None  # None: not the ServoBot firmware (nothing to verify)
    running_version: int | None  # what HELLO reported after the download; None if not asked


def flash_robot(
    port: str, image: StampImage, *, verify: bool = True, progress: Progress | None = None
) -> FlashOutcome:
    """Download ``image`` to the Stamp on ``port``; with ``verify``, check HELLO afterwards."""
    ser = open_port(port)
    try:
        report = StampLoader(ser, progress=progress).flash(image)
        want = image.firmware_version
        running = None
        if verify and want is not None:
            if progress:
                progress("verify", report.packets, report.packets)
            hello = StampLink(ser, name=port).hello()
            running = hello.firmware
            if running != want:
                raise VerifyError(
                    f"{port}: the download was acknowledged but the robot reports firmware "
                    f"{running}, the image is firmware {want}"
                )
        return FlashOutcome(report, want, running)
    finally:
        ser.close()
