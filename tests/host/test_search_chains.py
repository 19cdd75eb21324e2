"""Several search chains a punctuation (``PALConfig.search_chains``): each searches the
corrected model with the whole budget and is carried on to the next; the best any found is
tested; the chains are saved with the run and resumed bit for bit; the setting's bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import parse_turn_cycle, simulate
from pac_host.errors import InputError
from pac_host.learning import pal, profiles
from pac_host.robot.evolve import EvolveConfig
from tests.host.test_explore import run_recorded
from tests.host.test_pal import resumed_and_whole


def _cfg(chains: int, **kw) -> pal.PALConfig:
    return replace(profiles.apply("default", pal.PALConfig()), search_chains=chains,
                   shapes="none", explore=0.0, search_evaluations=6_000, generations=80,
                   cga_population=32, **kw)


def test_the_best_any_chain_found_is_tested_next():
    records, states = run_recorded(_cfg(3))
    assert len(records) == 3
    spread = searched = 0
    for rec, st in zip(records, states, strict=True):
        scores = rec["search"]["chain_scores"]
        assert len(scores) == 3 and rec["search"]["best_chain"] == scores.index(max(scores))
        spread += len(set(scores)) > 1
        assert len(st.search["others"]) == 2  # chains 1 and 2 carried on
        if max(scores) < 0:  # every chain's budget went to the last punctuation's overrun
            assert rec["search"]["evaluations"] == 0
            continue
        searched += 1
        # the front of the population, the next test, is what the best chain scored there
        front = simulate(st.models[0], st.cga_pop[:1], 200, st.model_effects).score()[0]
        assert int(front) == max(scores)
    assert spread >= 1 and searched >= 2  # the chains do not all end alike
    for rec, st in zip(records[1:], states[:-1], strict=True):
        assert np.array_equal(parse_turn_cycle(rec["tests"][0]), st.cga_pop[0])


def test_one_chain_is_the_run_it_was_and_more_chains_search_more():
    one, _ = run_recorded(_cfg(1))
    assert all("chain_scores" not in r["search"] for r in one)
    many, _ = run_recorded(_cfg(3))
    # chain 0 is the same search as the single chain's up to the first punctuation's end
    assert many[0]["search"]["chain_scores"][0] == one[0]["search"]["best_score"]
    assert max(many[0]["search"]["chain_scores"]) >= one[0]["search"]["best_score"]


@pytest.mark.parametrize("library_restarts", [True, False])
def test_each_other_chain_is_given_its_own_point_and_not_the_best_chain_s(monkeypatch,
                                                                          library_restarts):
    """Chain 0 is given the library, the population's best and the operational turn cycle;
    chains 1.. the library and their own carried point only, so they do not all start again
    from the best chain's find (which had them end most punctuations alike). With library
    restarts (the default) the finds are carried, apart from the library's sources; without,
    they are sources after the library's."""
    from pac_host.search import anytime, shapes

    library = len(shapes.load("builtin").sources())
    calls = []
    real = anytime.advance

    def spy(*args, **kw):
        if kw.get("shapes"):
            chain = kw.get("chain")
            if library_restarts:
                assert len(kw["shapes"]) == library
                extra = kw.get("carried", ())
            else:
                assert not kw.get("carried")
                extra = kw["shapes"][library:]
            calls.append((None if chain is None else chain.to_json(),
                          [genes.tolist() for genes, _ in extra]))
        return real(*args, **kw)

    monkeypatch.setattr(anytime, "advance", spy)
    cfg = replace(_cfg(3), shapes="builtin", library_restarts=library_restarts)
    records, _ = run_recorded(cfg)
    assert len(calls) == 3 * len(records)  # three chains a punctuation, each with sources
    for k in range(len(records)):
        first, *rest = calls[3 * k: 3 * k + 3]
        assert len(first[1]) == 2  # the population's best and the operational turn cycle
        for chain, extra in rest:
            if chain is None:  # the first punctuation: no point of its own yet
                assert extra == []
            else:
                own = chain["x"] if chain["x"] is not None else chain["origin"][0]
                assert extra == [own]


def test_the_chains_are_saved_and_resumed_bit_for_bit():
    cfg = replace(_cfg(2), generations=120, shapes="builtin")
    resumed, whole, saved = resumed_and_whole(cfg, 4)
    assert resumed == whole
    assert len(saved["search"]["others"]) == 1
    saved["search"]["others"] = [[1, 2]]
    with pytest.raises(InputError, match="other chains"):
        pal.state_from_json(saved)


def test_search_chains_is_checked():
    for bad, match in ((pal.PALConfig(search_chains=2), "anytime"),
                       (pal.PALConfig(search="ils", search_evaluations=10, search_chains=0),
                        "search-chains")):
        with pytest.raises(InputError, match=match):
            bad.check()
    cfg = EvolveConfig(search="ils", search_evaluations=10, correction="fit", search_chains=4)
    assert cfg.pal().search_chains == 4
    cfg.check()


@pytest.mark.parametrize("args", [["--search-chains", "0"], ["--search-chains", "x"],
                                  ["--search-chains", "2", "--profile", "paper"]])
def test_bad_search_chains_is_one_line_and_exit_2(tmp_path, args):
    res = CliRunner().invoke(main, ["experiment", "--seeds", "1", "--generations", "40",
                                    "--out", str(tmp_path / "x"), *args])
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1 and "search-chains" in res.output
    assert not (tmp_path / "x" / "log.jsonl").exists()


def test_a_state_saved_before_several_chains_resumes_with_one(tmp_path):
    _, states = run_recorded(_cfg(1))
    doc = json.loads(json.dumps(pal.state_to_json(states[-1], np.random.default_rng(0))))
    assert "others" not in doc["search"]
    state, _ = pal.state_from_json(doc)
    assert "others" not in state.search


def test_the_default_profile_runs_eight_chains_and_the_option_overrides_it(tmp_path):
    """evolve without --search-chains takes the profile's count (eight in the default, one in
    the paper's CGA); typed, the option replaces it."""
    small = ["--generations", "0", "--budget", "100", "--initial-generations", "5",
             "--cga-population", "16"]
    cheap = ["--search-evaluations", "2000"]
    for name, args, chains in (("default", cheap, 8), ("one", [*cheap, "--search-chains", "1"], 1),
                               ("paper", ["--profile", "paper"], 1)):
        out = tmp_path / name
        res = CliRunner().invoke(main, ["evolve", "--out", str(out), *small, *args])
        assert res.exit_code == 0, res.output
        assert json.loads((out / "config.json").read_text())["search_chains"] == chains
