"""The turn-cycle searches: neighbourhoods, climbs to real local optima, exact evaluation
budgets, reproducibility, and the search checked on tables it was not built on."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import (
    fitness_of_score,
    format_turn_cycle,
    parse_turn_cycle,
    search_score,
    simulate,
)
from pac_host.model import measured_table, parse_effect, shifted_table
from pac_host.model.kinematics import loop_moves
from pac_host.search import cga
from pac_host.search.kicks import (
    closing_kick,
    closure_error,
    gene_change_moves,
    kick,
    loop_table,
)
from pac_host.search.local import Exhausted, Objective, climb
from pac_host.search.neighbours import _VALUES, canonical, neighbours, pair_neighbours
from pac_host.search.optimize import OptimizeConfig, optimize


def _score(rows, genes, budget=200, effects=()):
    return simulate(rows, genes, budget, effects).score()


def _search_score(rows, genes, budget=200):
    cov = simulate(rows, genes, budget)
    return search_score(cov.fitness, cov.reached_at, cov.repeat_visits, budget)


def test_canonical_form_walks_the_same_path():
    rng = np.random.default_rng(0)
    pop = cga.random_population(rng, 500)
    pop[..., 1] //= rng.integers(1, 9, size=pop.shape[:2])
    rows = shifted_table().rows
    np.testing.assert_array_equal(_score(rows, pop, 120), _score(rows, canonical(pop, 120), 120))


def test_neighbourhood_is_every_distinct_single_gene_change():
    x = parse_turn_cycle("12:60,3:10,0:0,5:0,22:70" if False else "12:60,3:10,0:0,5:3")
    n = neighbours(x, 200)
    diff = (n != canonical(x, 200)).any(axis=2).sum(axis=1)
    assert (diff == 1).all()  # one gene changed each time
    assert len(np.unique(n.reshape(len(n), -1), axis=0)) == len(n)  # no duplicates
    # slots 0, 1, 3 and the first empty one (2); the empty run 4..8 after gene 3 too
    assert sorted({int(np.flatnonzero(d)[0]) for d in (n != canonical(x, 200)).any(axis=2)}) \
        == [0, 1, 2, 3, 4]
    # a gene the budget never reaches is not changed
    assert not (neighbours(parse_turn_cycle("12:63,12:63,3:5"), 100)[:, 2]
                != [0, 0]).any()


def test_small_changes_keep_the_gene_id_or_its_repetitions():
    x = canonical(parse_turn_cycle("0:5,7:12,3:40"), 200)
    for j in range(3):
        changed = neighbours(x, 200, only=j, small=True)[:, j]
        assert ((changed[:, 0] == x[j, 0]) | (changed[:, 1] == x[j, 1])).all()
        assert len(np.unique(changed, axis=0)) == len(changed)
        # 31 other ids, 62 other repetitions, and the empty gene if the id is already 0
        assert len(changed) == 31 + 62 + (x[j, 0] == 0)
        assert len(neighbours(x, 200, only=j)) == 32 * 63



@pytest.mark.parametrize("text, budget", [("12:60,3:10,0:0,5:3,7:1", 200),
                                          ("1:63,2:1,3:2,4:62,5:30,6:3,7:4,8:5,9:6", 10**6),
                                          ("1:63,2:1,3:2,4:62,5:30", 100), ("12:5", 200)])
def test_paired_changes_are_every_two_gene_repetition_change_pair_by_pair(text, budget):
    x = canonical(parse_turn_cycle(text), budget)
    active = [j for j in range(9) if x[j, 1] > 0 and x[:j, 1].sum() < budget]
    expected = []  # pairs in order, then (da, db) in order: the order a climb's ties go by
    for a, i in enumerate(active):
        for j in active[a + 1:]:
            for da in range(-3, 4):
                for db in range(-3, 4):
                    y = x.copy()
                    y[i, 1] += da
                    y[j, 1] += db
                    if (da or db) and 1 <= y[i, 1] <= 63 and 1 <= y[j, 1] <= 63:
                        expected.append(y)
    got = pair_neighbours(x, budget)
    assert got.shape == (len(expected), 9, 2)
    if expected:
        np.testing.assert_array_equal(got, np.array(expected))

def test_climb_ends_at_a_local_optimum():
    rows = measured_table().rows
    obj = Objective(rows, 200)
    x = cga.random_population(np.random.default_rng(3), 1)[0]
    best, score = climb(x, int(obj(x[None])[0]), obj, np.random.default_rng(4))
    assert score == _search_score(rows, best)[0]
    assert _search_score(rows, neighbours(best, 200)).max() <= score
    assert _search_score(rows, pair_neighbours(best, 200)).max() <= score


def test_a_sampled_climb_is_cheaper_and_ends_where_no_cheap_or_paired_change_improves():
    """A climb that scores a random share of each gene's any-change neighbourhood spends
    fewer evaluations; it still ends where no change of one gene's id or repetitions alone and
    no paired repetition change is better, and climbs from every start."""
    rows = measured_table().rows
    starts = cga.random_population(np.random.default_rng(8), 4)
    for k, x in enumerate(starts):
        costs = []
        for sample in (1.0, 0.1):
            obj = Objective(rows, 200)
            x0 = int(obj(x[None])[0])
            best, score = climb(x, x0, obj, np.random.default_rng(k), sample)
            costs.append(obj.evaluations)
            assert score == _search_score(rows, best)[0] and score > x0
        small = np.concatenate([neighbours(best, 200, only=j, small=True)
                                for j in range(9) if (best[j] != 0).any()])
        assert _search_score(rows, small).max() <= score
        assert _search_score(rows, pair_neighbours(best, 200)).max() <= score
        assert costs[1] < costs[0], costs
    with pytest.raises(ValueError, match="sample"):
        climb(starts[0], 0, Objective(rows, 200), np.random.default_rng(0), 0.0)


def test_objective_counts_evaluations_exactly_and_stops():
    obj = Objective(measured_table().rows, 200, limit=250)
    pop = cga.random_population(np.random.default_rng(1), 200)
    obj(pop)
    assert len(obj(pop)) == 50 and obj.evaluations == 250
    with pytest.raises(Exhausted):
        obj(pop)
    keys = _search_score(measured_table().rows, pop)
    assert obj.best_search_score == keys.max()
    # the best by search score, and its coverage score as the rest of the project ranks
    assert obj.best_score == _score(measured_table().rows, pop)[np.argmax(keys)]
    assert fitness_of_score(obj.best_score) == obj.fitness(obj.best_search_score)


def test_optimize_is_reproducible_and_jobs_do_not_change_it():
    cfg = OptimizeConfig(evaluations=30_000, chains=2, seed=7)
    a = optimize(shifted_table().rows, cfg)
    b = optimize(shifted_table().rows, cfg, jobs=2)
    assert a["genes"] == b["genes"] and a["evaluations"] == b["evaluations"] == 30_000
    strip = [{k: v for k, v in c.items() if k != "seconds"} | {"trace": [
        {k: v for k, v in t.items() if k != "seconds"} for t in c["trace"]]}
        for c in a["chains"]]
    assert strip == [{k: v for k, v in c.items() if k != "seconds"} | {"trace": [
        {k: v for k, v in t.items() if k != "seconds"} for t in c["trace"]]}
        for c in b["chains"]]
    cov = simulate(shifted_table().rows, np.array(a["genes"]), 200)
    assert a["fitness"] == cov.row(0)["fitness"]


def test_search_beats_the_cga_on_robots_it_was_not_built_on():
    """The same number of evaluations (the CGA's 1,500 generations of 128) on tables with
    random row errors and with effects: the search's best against the paper's CGA's best."""
    rng = np.random.default_rng(11)
    base = measured_table().rows
    robots = [(base + rng.normal(0, 1.0, base.shape) * (rng.random((32, 1)) < 0.5), ()),
              (base, (parse_effect("yaw_bias:delta=-1.2"), parse_effect("stride_scale:a=0.8"),
                      parse_effect("floor_slope:s=0.6,theta=120"))),
              (base + rng.normal(0, 0.5, base.shape), (parse_effect("turn_scale:c=1.3"),))]
    n = 128 * 1500
    found, cga_best = [], []
    for rows, effects in robots:
        res = optimize(rows, OptimizeConfig(evaluations=n, seed=1, shapes="none"), effects)
        _, best = cga.evolve(rows, cga.random_population(rng, 128), 1499, rng, effects=effects)
        assert res["evaluations"] == n
        found.append(res["fitness"])
        cga_best.append(int(fitness_of_score(best.max())))
    assert sum(found) > sum(cga_best), (found, cga_best)
    assert all(f >= c - 2 for f, c in zip(found, cga_best, strict=True)), (found, cga_best)


def test_optimize_command_prints_and_writes_the_result(tmp_path):
    out, png = tmp_path / "best.json", tmp_path / "best.png"
    res = CliRunner().invoke(main, ["optimize", "--table", "measured", "--evaluations", "20000",
                                    "--seed", "3", "--json", str(out), "--plot", str(png)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert f"best turn cycle on measured: {doc['turn_cycle']}" in res.output
    assert f"fitness: {doc['fitness']}" in res.output
    sim = CliRunner().invoke(main, ["simulate", "--table", "measured", "--turn-cycle",
                                    doc["turn_cycle"], "--json"])
    assert json.loads(sim.output)["fitness"] == doc["fitness"]
    assert doc["settings"]["seed"] == 3 and doc["evaluations"] == 20000
    assert doc["chains"][0]["trace"][-1]["fitness"] == doc["fitness"]
    assert png.stat().st_size > 0


@pytest.mark.parametrize("args, message", [
    (["--seconds", "0"], "--seconds must be in (0,"),
    (["--seconds", "-3"], "--seconds must be in (0,"),
    (["--seconds", "1e12"], "--seconds must be in (0,"),
    (["--evaluations", "0"], "--evaluations must be 1.."),
    (["--evaluations", "-5"], "--evaluations must be 1.."),
    (["--evaluations", "100000000000000"], "--evaluations must be 1.."),
    (["--evaluations", "10", "--budget", "-1"], "--budget must be 1..65535"),
    (["--evaluations", "10", "--budget", "10000000"], "--budget must be 1..65535"),
    (["--evaluations", "10", "--chains", "0"], "--chains must be 1..1024"),
    (["--evaluations", "10", "--sample", "0"], "--sample"),
    (["--evaluations", "10", "--sample", "1.5"], "--sample"),
    (["--evaluations", "ten"], "ten"),
    (["--evaluations", "10", "--table", "nowhere.json"], "nowhere.json"),
])
def test_optimize_bad_input_is_one_line_and_exit_2(args, message):
    res = CliRunner().invoke(main, ["optimize", *args])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.output


def _count_restarts(monkeypatch) -> list:
    from pac_host.search import local

    calls = []
    real = local.cga_start

    def counted(objective, rng, divisor=1):
        out = real(objective, rng, divisor)  # a start cut by the budget is made again
        calls.append((objective.evaluations, divisor))
        return out

    monkeypatch.setattr(local, "cga_start", counted)
    return calls


def test_a_chain_carried_across_budgets_restarts_when_it_stalls(monkeypatch):
    """Anytime PAL hands the search a small budget per punctuation: the chain carries its
    stall count from one budget to the next, so it restarts from a new basin once it stalls,
    however the budget is cut; with endless patience it stays in its first."""
    from pac_host.search import local
    from pac_host.search.local import Chain

    rows = shifted_table().rows
    for patience, restarted in ((2, True), (10**6, False)):
        calls = _count_restarts(monkeypatch)
        chain, rng = Chain(), np.random.default_rng(3)
        for _ in range(10):
            objective = Objective(rows, limit=100_000)
            chain.run(objective, rng, patience)
            assert objective.evaluations == 100_000
            assert chain.stale <= patience
        assert (len(calls) > 1) == restarted, calls
        divisors = local.LOOP_DIVISORS
        assert [d for _, d in calls] == [divisors[k % len(divisors)] for k in range(len(calls))]
        back = Chain.from_json(json.loads(json.dumps(chain.to_json())))
        assert back.stale == chain.stale
        assert (back.x is None and chain.x is None) or (back.x == chain.x).all()


def test_a_carried_chain_climbs_again_only_when_the_model_has_changed(monkeypatch):
    """On the same model the chain's point is still a local optimum: the next budget goes to
    kicks at once. On a changed model it is re-scored and climbed first."""
    from pac_host.search import local

    rows = shifted_table().rows
    chain, rng = local.Chain(), np.random.default_rng(5)
    chain.run(Objective(rows, limit=120_000), rng, 50)
    starts = []
    real = local.climb

    def recorded(x, score, objective, rng=None, sample=1.0):
        starts.append(canonical(x, objective.budget))
        return real(x, score, objective, rng, sample)

    monkeypatch.setattr(local, "climb", recorded)
    for table, climbs_first in ((rows, False), (rows + 0.5, True)):
        starts.clear()
        x = chain.x.copy()
        chain.run(Objective(table, limit=60_000), rng, 50)
        assert (starts[0] == x).all() == climbs_first


def test_the_best_known_turn_cycles_score_as_recorded():
    """`experiment`, the benchmarks and the docs measure against the package's record
    (pac_host/model/best_known.json; bench/known_best.py reads the same, which
    bench/test_tools.py checks): each record holds, simulated on its robot's table at the
    record's budget."""
    from pac_host.coverage.placement import parse_placement, placed_fitness, summary
    from pac_host.coverage.walks import walk_many
    from pac_host.model import best_known, robots
    from pac_host.model.step_noise import parse_step_noise

    records = best_known.entries()
    assert set(records) >= {"measured", "shifted", *robots.ROBOTS}  # every built-in robot's
    assert records["shifted"]["fitness"] == 49
    assert records["shifted"]["turn_cycle"] == "12:2,11:2,22:11,18:4,13:3,4:5,9:6,6:2,0:3"
    budget = best_known.budget()
    assert budget == 200
    for name, rec in records.items():
        table = best_known.builtin_table(name)
        assert best_known.robot_of(table) == name
        cov = simulate(table.rows, parse_turn_cycle(rec["turn_cycle"]), budget, table.effects)
        assert cov.row(0)["fitness"] == rec["fitness"], name
        if "placed" in rec:  # the best known for a robot placed by hand
            pl = rec["placed"]
            fit = placed_fitness(table.rows, parse_turn_cycle(pl["turn_cycle"]),
                                 parse_placement(pl["placement"]), pl["walks"],
                                 np.random.default_rng(pl["seed"]), budget, table.effects)
            assert summary(fit)["mean"] == pl["mean"], name
        for rb in rec.get("robust", []):  # the best known with step noise: simulate --walks
            noise = parse_step_noise(rb["step_noise"])
            assert best_known.robust(name, noise) is rb
            figs, _ = walk_many(table.rows, parse_turn_cycle(rb["turn_cycle"]), rb["walks"],
                                budget, table.effects, noise,
                                np.random.default_rng(rb["seed"]))
            assert round(float(figs.fitness.mean()), 2) == rb["mean"], (name, rb["step_noise"])
    assert {rb["step_noise"] for rb in records["shifted"]["robust"]} >= {"0.3,1", "0.15,0.5"}


def test_a_closing_kick_keeps_a_repeating_loops_net_move():
    """A closing kick changes two genes of a loop the budget repeats and brings the loop's net
    move back near the kicked loop's; a random kick of two genes does not."""
    rng = np.random.default_rng(5)
    for table in (measured_table(), shifted_table()):
        repeated = loop_table(table.rows)
        for text in ("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6", "12:20,3:10,28:15,6:4"):
            x = parse_turn_cycle(text)
            near, far = [], []
            for _ in range(30):
                y = closing_kick(x, rng, 2, 200, repeated)
                assert (y != x).any(axis=1).sum() <= 2
                assert y[:, 1].sum() < 200  # still a repeating loop
                near.append(float(closure_error(y, x, repeated)))
                far.append(float(closure_error(kick(x, rng, 2, 200), x, repeated)))
            assert np.median(near) < np.median(far) / 4


def test_a_loop_the_budget_does_not_repeat_is_kicked_at_random():
    x = parse_turn_cycle("12:60,3:63,20:63,5:40")  # 226 gait cycles: walked once in 200
    repeated = loop_table(shifted_table().rows)
    a = closing_kick(x, np.random.default_rng(9), 2, 200, repeated)
    b = kick(x, np.random.default_rng(9), 2, 200)
    assert (a == b).all() and (a != x).any()


def test_gene_change_moves_are_the_net_moves_of_the_changed_loops():
    """The closing kick's shortcut (moves of the genes before and after the changed one) gives
    the net move of every single-gene change as the loop walked whole would."""
    repeated = loop_table(measured_table().rows)
    y = parse_turn_cycle("10:1,25:8,21:11,17:2,0:0,5:8,22:3,11:1,1:6")
    fast = gene_change_moves(y, repeated)
    for j in range(len(y)):
        changed = np.repeat(y[None], len(_VALUES), axis=0)
        changed[:, j] = _VALUES
        np.testing.assert_allclose(fast[j], loop_moves(changed, repeated), atol=1e-9)


def test_a_tiny_deadline_returns_the_start(tmp_path):
    """--seconds shorter than one batch still scores the chains' starts, and returns the best
    as a turn cycle `simulate` agrees with; never a traceback."""
    out = tmp_path / "best.json"
    res = CliRunner().invoke(main, ["optimize", "--seconds", "0.01", "--chains", "2",
                                    "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    genes = parse_turn_cycle(doc["turn_cycle"])
    assert fitness_of_score(_score(shifted_table().rows, genes)) == doc["fitness"] > 0
    assert len(doc["chains"]) == 2 and all(c["evaluations"] > 0 for c in doc["chains"])
    # a deadline already past stops a search only once it has scored something
    obj = Objective(shifted_table().rows, deadline=0.0)
    pop = cga.random_population(np.random.default_rng(0), 5)
    assert len(obj(pop)) == 5 and obj.best is not None
    with pytest.raises(Exhausted):
        obj(pop)


def test_shorter_loop_listings_stop_at_the_deadline():
    from pac_host.search.kicks import loop_table
    from pac_host.search.shorten import shorter_loops, shorter_windows

    x = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # a 44-cycle loop
    table = loop_table(shifted_table().rows)
    assert len(shorter_loops(x, table, 200)) > 0
    assert len(shorter_loops(x, table, 200, expired=lambda: True)) == 0
    assert len(shorter_windows(x, table, 200, expired=lambda: True)) == 0
    calls = []  # a deadline passing after the first window: that window's proposals alone
    first = shorter_windows(x, table, 200, expired=lambda: calls.append(1) or len(calls) > 1)
    whole = shorter_windows(x, table, 200)
    assert 0 < len(first) < len(whole) and (first == whole[:len(first)]).all()


def test_chains_run_in_turn_share_the_time_left(monkeypatch):
    """A chain that overruns its share takes the excess from the next ones: the search ends
    one overrun past --seconds, not one per chain."""
    from pac_host.search import optimize as opt

    class Clock:
        now = 0.0

        def perf_counter(self):
            return self.now

    clock, shares = Clock(), []

    def chain(rows, effects, cfg, c, seconds, evaluations):
        shares.append(seconds)
        clock.now += seconds + 1.0  # each chain overruns by a second
        return {"chain": c, "genes": [[12, 1]] + [[0, 0]] * 8, "score": 1,
                "evaluations": 1, "seconds": seconds + 1.0, "trace": []}

    monkeypatch.setattr(opt, "time", clock)
    monkeypatch.setattr(opt, "run_chain", chain)
    monkeypatch.setattr(opt, "_warm_up", lambda *a: None)
    optimize(shifted_table().rows, OptimizeConfig(seconds=12.0, chains=3))
    assert shares == [4.0, 3.5, 2.5] and clock.now == 13.0


def test_ctrl_c_prints_and_writes_the_best_so_far(monkeypatch, tmp_path):
    """KeyboardInterrupt mid-search: the best found so far is printed and written to --json
    and --plot, one line says so, exit 130; before anything was scored, the line alone."""
    from pac_host.search import optimize as opt

    pop = cga.random_population(np.random.default_rng(7), 64)

    def interrupted(objective, *args, **kwargs):
        objective(pop)
        raise KeyboardInterrupt

    monkeypatch.setattr(opt, "restarts", interrupted)
    out, png = tmp_path / "best.json", tmp_path / "best.png"
    res = CliRunner().invoke(main, ["optimize", "--seconds", "30", "--chains", "3",
                                    "--json", str(out), "--plot", str(png)])
    assert res.exit_code == 130, res.output
    doc = json.loads(out.read_text())
    best = pop[int(np.argmax(_search_score(shifted_table().rows, pop)))]
    assert doc["turn_cycle"] == format_turn_cycle(best) and doc["interrupted"] is True
    assert len(doc["chains"]) == 1  # the chains after the interrupted one never started
    assert f"best turn cycle on shifted: {doc['turn_cycle']}" in res.output
    last = res.output.strip().splitlines()[-1]
    assert last.startswith("pac-host: interrupted") and "Traceback" not in res.output
    assert png.stat().st_size > 0

    def at_once(objective, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(opt, "restarts", at_once)
    res = CliRunner().invoke(main, ["optimize", "--seconds", "30", "--json",
                                    str(tmp_path / "none.json")])
    assert res.exit_code == 130 and not (tmp_path / "none.json").exists()
    assert res.output.strip().splitlines()[-1] == (
        "pac-host: interrupted (work already written is kept)")
