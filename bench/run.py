"""Run every benchmark module (bench/bench_*.py) and write one JSON file of results.

Each module defines ``run(quick: bool) -> dict`` returning its figures, including the targets it
is checked against and whether they were met.
Usage: ``python bench/run.py --out FILE [--only NAME] [--quick]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=str(HERE / "results" / "bench.json"))
    ap.add_argument("--only", action="append", default=[], help="run only bench_NAME.py")
    ap.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    args = ap.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    results = json.loads(out.read_text()) if out.exists() else {}
    mods = sorted(HERE.glob("bench_*.py"))
    if args.only:
        mods = [m for m in mods if m.stem.removeprefix("bench_") in args.only]
    failed = []
    for path in mods:
        name = path.stem.removeprefix("bench_")
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = mod  # so a process pool's workers can pickle its functions
        spec.loader.exec_module(mod)
        t0 = time.perf_counter()
        res = mod.run(quick=args.quick)
        res["bench_wall_s"] = round(time.perf_counter() - t0, 2)
        res["machine"] = {"python": platform.python_version(),
                          "cpu": platform.processor() or platform.machine()}
        results[name] = res
        out.write_text(json.dumps(results, indent=1) + "\n")
        ok = all(t.get("met", True) for t in res.get("targets", {}).values())
        if not ok:
            failed.append(name)
        print(f"{name}: " + json.dumps(res.get("targets", res), indent=None), flush=True)
    print(f"wrote {out}")
    if failed:
        print("targets missed: " + ", ".join(failed), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
