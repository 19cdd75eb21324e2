"""bench/bench_demo.py measures what `make demo`'s evolve does: it must read that command from
the Makefile, and compute the figures its targets are checked on from an evolve log."""

from __future__ import annotations

import json

import bench_demo  # bench/conftest.py puts bench/ on the path
import pytest


def test_the_demo_evolve_arguments_come_from_the_makefile(tmp_path):
    args = bench_demo.demo_evolve_args()
    assert "--out" not in args and "--seed" in args  # the demo is seeded, so reproducible
    mk = tmp_path / "Makefile"
    mk.write_text("x:\n\techo\n\ndemo: $(STAMP)\n\trm -rf out\n"
                  "\t$(BIN)/pac-host evolve --out $(OUT)/d --generations 8 --seed 3\n\nz:\n")
    assert bench_demo.demo_evolve_args(mk) == ["--generations", "8", "--seed", "3"]
    mk.write_text("demo:\n\t$(BIN)/pac-host experiment --seeds 2\n")
    with pytest.raises(ValueError, match="no pac-host evolve"):
        bench_demo.demo_evolve_args(mk)


def test_figures_of_an_evolve_log(tmp_path):
    def rec(op, pred, obs):
        return {"operational": "1:2", "operational_fitness": op,
                "predicted": [{"fitness": f} for f in pred],
                "observed": [{"fitness": f} for f in obs]}
    recs = [rec(9, [40, 20, 20], [4, 9, 9]), rec(44, [44, 23, 30], [44, 23, 38]),
            rec(45, [45, 44, 44], [45, 44, 44]), rec(45, [44, 45, 44], [44, 45, 45]),
            rec(45, [44, 44, 44], [44, 44, 44])]
    (tmp_path / "log.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    f = bench_demo.figures(tmp_path, best_known=50)
    assert f["final"] == 45 and f["fraction_of_best_known"] == 0.9
    assert f["operational_by_punctuation"] == [9, 44, 45, 45, 45]
    assert f["prediction_errors"][0] == [36, 11, 11] and f["last_max_error"] == 1
