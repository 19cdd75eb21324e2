"""Moves finished across budgets (``finish_moves``): a chain carried from one punctuation's
budget to the next ends the move it is in when the budget runs out and pays the excess from
its next budget, where a chain cut at the budget lost every move costing about one; the
setting reaches the chains from PAL."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pac_host.coverage import simulate
from pac_host.learning import pal, profiles
from pac_host.model import shifted_table
from pac_host.search import anytime, cga
from pac_host.search.local import Chain, Exhausted, Objective
from tests.host.test_explore import run_recorded

SLICE = 400  # evaluations a budget: less than a climb from a random turn cycle costs


def _slices(finish: bool, n: int, seed: int = 3) -> tuple[list[int], Chain, int]:
    """``n`` budgets of SLICE on the shifted table for one carried chain from a random turn
    cycle: the evaluations each spent, the chain, and the best fitness its budgets found."""
    rows = shifted_table().rows
    rng = np.random.default_rng(seed)
    pop = cga.random_population(rng, 1)
    chain, spent, best = None, [], 0
    for _ in range(n):
        pop, rec, chain = anytime.advance(rows, pop, SLICE, rng, chain=chain, finish=finish)
        spent.append(rec["evaluations"])
        best = max(best, int(simulate(rows, pop[:1], 200).fitness[0]))
    return spent, chain, best


def test_a_finishing_objective_neither_cuts_a_batch_nor_stops_a_call():
    rows = shifted_table().rows
    pop = cga.random_population(np.random.default_rng(0), 10)
    cut = Objective(rows, limit=5)
    assert len(cut(pop)) == 5 and cut.spent()
    with pytest.raises(Exhausted):
        cut(pop)
    whole = Objective(rows, limit=5, finish=True)
    assert len(whole(pop)) == 10 and whole.spent()
    assert len(whole(pop)) == 10 and whole.evaluations == 20  # its caller stops, not it


def test_a_chain_given_budgets_smaller_than_a_move_climbs_only_when_it_finishes_moves():
    """Cut at each budget, the chain begins the same climb again every punctuation and never
    ends it; finishing its moves, it ends the climb, and what it spent past the budgets is
    exactly what it owes the next one."""
    n = 12
    cut, cut_chain, cut_best = _slices(False, n)
    done, done_chain, done_best = _slices(True, n)
    assert cut == [SLICE] * n and cut_chain.overrun == 0
    assert cut_chain.model is None  # never got past its first climb
    assert done_chain.model is not None  # its climb ended, on this model
    assert sum(done) == n * SLICE + done_chain.overrun
    assert max(done) > SLICE and 0 in done  # overspent, then skipped a budget it owed whole
    assert done_best > cut_best


def test_a_budget_the_chain_owes_whole_is_skipped_and_its_debt_saved():
    rows = shifted_table().rows
    rng = np.random.default_rng(0)
    pop = cga.random_population(rng, 1)
    chain = Chain(pop[0].copy(), starts=1, overrun=2 * SLICE + 7)
    pop2, rec, chain = anytime.advance(rows, pop, SLICE, rng, chain=chain, finish=True)
    assert rec["evaluations"] == 0 and chain.overrun == SLICE + 7
    assert np.array_equal(pop2, pop)
    assert Chain.from_json(chain.to_json()).overrun == SLICE + 7
    assert Chain.from_json({"x": None, "stale": 0}).overrun == 0  # saved before it: none owed
    _, rec, chain = anytime.advance(rows, pop, SLICE, rng, chain=chain, finish=True)
    assert rec["evaluations"] == 0 and chain.overrun == 7
    _, rec, chain = anytime.advance(rows, pop, SLICE, rng, chain=chain, finish=True)
    assert rec["evaluations"] >= SLICE - 7


@pytest.mark.parametrize("finish", [True, False])
def test_pal_s_chains_finish_their_moves_with_the_setting(finish):
    """Chain 0's budget a punctuation is spent exactly when cut; with finish_moves, over the
    run it spends the budgets and what it owes at the end."""
    cfg = replace(profiles.apply("default", pal.PALConfig()), search_chains=2, shapes="none",
                  explore=0.0, search_evaluations=3_000, generations=80, cga_population=32,
                  finish_moves=finish)
    records, states = run_recorded(cfg)
    spent = [r["search"]["evaluations"] for r in records]
    owed = states[-1].search["overrun"]
    if finish:
        assert sum(spent) == len(records) * 3_000 + owed
        assert max(spent) > 3_000
    else:
        assert spent == [3_000] * len(records) and owed == 0
