"""CLI start-up benchmark: the wall time of `pac-host --help` (the venv's own script, a fresh
process each run), which loads no command module (pac_host.cli.main.COMMANDS), against the
target of half a second. Shell completion of a command's name costs the same start-up."""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

TARGET_S = 0.5
PAC_HOST = Path(sys.executable).parent / "pac-host"


def _once(args: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(PAC_HOST), *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def run(quick: bool = False) -> dict:
    runs = 3 if quick else 11
    _once(["--help"])  # the first run fills the OS's file cache
    times = [_once(["--help"]) for _ in range(runs)]
    med = statistics.median(times)
    return {
        "command": "pac-host --help",
        "runs": runs,
        "median_s": round(med, 3),
        "min_s": round(min(times), 3),
        "max_s": round(max(times), 3),
        "targets": {"help_wall_s": {"target": TARGET_S, "median_s": round(med, 3),
                                    "met": med < TARGET_S}},
    }


if __name__ == "__main__":
    print(run(quick="--quick" in sys.argv))
