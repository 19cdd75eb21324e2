"""Checks of the bench's tools, on which docs figures rest (run by ``python bench/run.py
--only records``; not part of ``make test``): the reader of the best known turn cycles,
bench/exact_model_search.py's helpers and bench/search_variants.py."""

from __future__ import annotations

import pytest

from pac_host.coverage import parse_turn_cycle


def test_known_best_reads_the_packages_record():
    import known_best

    from pac_host.model import best_known

    records = best_known.entries()
    assert known_best.entries() == records and known_best.PATH == best_known.PATH
    assert known_best.fitnesses() == {k: v["fitness"] for k, v in records.items()}
    assert known_best.fitness("nobody") is None


def test_the_exact_model_bench_finds_when_the_model_became_exact_and_every_crossover():
    """bench/exact_model_search.py's two helpers, on which the docs' noisy_rows figures rest."""
    from exact_model_search import crossovers, exact_from

    def rec(err):
        return {"model_error": [{"F": err, "T": 0.0, "dH": -err}, {"F": 0.0, "T": 0.0, "dH": 0.0}]}

    # exact at punctuation 2, wrong again at 3: it counts from where it stays exact
    assert exact_from([rec(0.5), rec(0.0), rec(0.2), rec(0.0), rec(0.0)]) == 4
    assert exact_from([rec(0.0), rec(0.5)]) is None  # wrong at the end
    a = parse_turn_cycle("1:1,2:2,3:3")
    b = parse_turn_cycle("4:4,5:5,6:6")
    kids = crossovers([a, b])
    # one run of genes from the other parent: a and b themselves (an empty or a whole run),
    # 4:4,2:2,3:3  4:4,5:5,3:3  1:1,5:5,3:3  1:1,5:5,6:6  1:1,2:2,6:6  4:4,2:2,6:6, none twice
    assert len(kids) == 8
    assert any((k == parse_turn_cycle("1:1,5:5,3:3")).all() for k in kids)
    assert any((k == parse_turn_cycle("4:4,2:2,3:3")).all() for k in kids)


def test_search_variants_bench_compares_costs_seed_for_seed(tmp_path, capsys):
    """bench/search_variants.py, on which docs/explanation/learning.md's kick length and
    shorter-loop figures rest."""
    import search_variants

    out = search_variants.compare({"a": [40, 41, 42], "b": [41, 41, 40]})
    assert out["a"] == {"finals": [40, 41, 42], "mean": 41.0}
    assert (out["b"]["higher"], out["b"]["lower"], out["b"]["mean"]) == (1, 1, 40.667)
    res = search_variants.main(["--robots", "shifted", "--evaluations", "3000", "--seeds",
                                "0-1", "--shorten-after", "0,1", "--windows", "0,1", "--jobs", "1",
                                "--out", str(tmp_path / "v.json")])
    again = search_variants.one_run("shifted", str(tmp_path / "v.shifted.shapes.json"), 1,
                                    3000, 1, 1.0, 1, False)
    by = res["robots"]["shifted"]
    assert set(by) == {search_variants.label(c, k, w) for c in (0, 1) for k in (0, 1)
                       for w in (False, True)}
    assert by["cost 1, shorten after 1, pairs only"]["finals"][1] == again  # seed for seed
    assert res["pooled"]["cost 0, shorten after 0"]["finals"] == by["cost 0, shorten after 0"][
        "finals"]
    for bad in (["--robots", "nobody"], ["--seeds", "5-2"], ["--kick-length-costs", "0,-1"],
                ["--kick-length-costs", "0,0"], ["--shorten-after", "-1"],
                ["--shorten-after", "1.5"], ["--windows", "2"], ["--windows", "1,1"]):
        with pytest.raises(SystemExit) as e:
            search_variants.main([*bad, "--out", str(tmp_path / "b.json")])
        assert e.value.code == 2
        assert len(capsys.readouterr().err.strip().splitlines()[-1]) > 0
