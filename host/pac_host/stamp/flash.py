"""Flash the robot and check the result: the BS2 download, then HELLO from the new firmware.

Sits between the CLI and the loader: opens the port (DTR deasserted, as the protocol requires),
runs :class:`pac_host.stamp.loader.StampLoader`, and, when the image is the ServoBot firmware,
asks the freshly started program HELLO and compares the firmware version it reports with the
image's. Nothing here prints; progress goes to the callback.

A download that fails once the Stamp answered (a damaged echo, a packet not acknowledged) is
tried again from the reset, up to ``attempts`` times: a new download replaces whatever the
broken one left. If every attempt fails, the error says what the Stamp holds now: its old
program if no packet was written, else an incomplete one that answers nothing until a download
completes (so `pac-host flash` again is the way back).
"""

from __future__ import annotations

from dataclasses import dataclass

from pac_host.stamp.image import StampImage
from pac_host.stamp.loader import FlashError, FlashReport, NoStampError, Progress, StampLoader
from pac_protocol.link import StampLink
from pac_protocol.port import open_port


class VerifyError(FlashError):
    """The download completed but the robot does not run the image's firmware."""


@dataclass(frozen=True)
class FlashOutcome:
    report: FlashReport
    image_version: int | None  # None: not the ServoBot firmware (nothing to verify)
    running_version: int | None  # what HELLO reported after the download; None if not asked
    failures: tuple[str, ...] = ()  # why each download tried again failed


FLASH_ATTEMPTS = 3


def _download(loader: StampLoader, image: StampImage, attempts: int, progress: Progress | None
              ) -> tuple[FlashReport, tuple[str, ...]]:
    """The download, tried again from the reset after a failure (module docstring)."""
    failures: list[str] = []
    while True:
        try:
            return loader.flash(image), tuple(failures)
        except NoStampError:
            raise  # nothing answers: trying again cannot help
        except FlashError as e:
            failures.append(str(e))
            if len(failures) >= attempts:
                n = loader.packets_written
                state = (f"{n} of {len(image.packets)} packets were written: the Stamp holds "
                         "no whole program and answers nothing until a download completes"
                         if n else "no packet was written: the Stamp keeps its old program")
                raise FlashError(f"{e}; the download failed {attempts} times; {state}. Run "
                                 "`pac-host flash` again") from None
            if progress:
                progress("retry", len(failures), attempts)


def flash_robot(
    port: str, image: StampImage, *, verify: bool = True, progress: Progress | None = None,
    attempts: int = FLASH_ATTEMPTS,
) -> FlashOutcome:
    """Download ``image`` to the Stamp on ``port`` (tried up to ``attempts`` times); with
    ``verify``, check HELLO afterwards."""
    ser = open_port(port)
    try:
        report, failures = _download(StampLoader(ser, progress=progress), image, attempts,
                                     progress)
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
        return FlashOutcome(report, want, running, failures)
    finally:
        ser.close()
