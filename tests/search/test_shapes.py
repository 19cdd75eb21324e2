"""The library of good sweeps: re-expressing a path on another table, and the searches'
starts made from it (pac_host.search.retarget, pac_host.search.shapes)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import format_turn_cycle, parse_turn_cycle, simulate
from pac_host.learning import pal
from pac_host.model import measured_table, robots, shifted_table
from pac_host.model.kinematics import loop_moves
from pac_host.search import local, shapes
from pac_host.search.kicks import loop_table
from pac_host.search.local import Chain, Objective
from pac_host.search.retarget import retarget

LIB = shapes.load("builtin")


def _fitness(table, genes) -> np.ndarray:
    return simulate(table.rows, np.atleast_3d(genes).reshape(-1, 9, 2), 200,
                    table.effects).fitness


SHARP = [s for s in LIB.shapes if s.step_noise is None]


def _name(s: shapes.Shape) -> str:
    return f"{s.table}-{s.fitness if s.step_noise is None else s.step_noise}"


@pytest.mark.parametrize("shape", SHARP, ids=_name)
def test_each_sweep_of_the_library_scores_as_recorded_on_its_table(shape):
    assert int(_fitness(shapes.table_of(shape.table), shape.genes)[0]) == shape.fitness


@pytest.mark.parametrize("shape", LIB.shapes, ids=_name)
def test_a_sweep_re_expressed_on_its_own_table_walks_the_same_loop(shape):
    table = shapes.table_of(shape.table)
    moves = loop_table(table.rows, table.effects)
    first = retarget(shape.genes, moves, moves)[0]
    assert np.allclose(loop_moves(first, moves), loop_moves(shape.genes, moves), atol=1e-9)
    assert _fitness(table, first)[0] == _fitness(table, shape.genes)[0]


def test_the_robust_best_knowns_are_starts_for_a_noisy_search_only():
    """The library carries every robust record of the best knowns (found for a noisy robot,
    on that robot); a noise-free search's sources are the sharp sweeps alone, in their order,
    so its starts are what they were before there were robust sweeps."""
    from pac_host.model import best_known

    robust = [s for s in LIB.shapes if s.step_noise is not None]
    records = {(name, rb["turn_cycle"], rb["step_noise"])
               for name, rec in best_known.entries().items() for rb in rec.get("robust", [])}
    assert records and {(s.found_on, format_turn_cycle(s.genes), s.step_noise)
                        for s in robust} == records
    sharp, noisy = LIB.sources(), LIB.sources(noisy=True)
    assert len(sharp) == len(SHARP) and len(noisy) == len(LIB.shapes)
    assert all(np.array_equal(a[0], s.genes) for a, s in zip(sharp, SHARP, strict=True))
    assert all(s.found_on != "shifted" for s in LIB.without("shifted").shapes)


def test_a_library_file_keeps_each_sweep_s_step_noise(tmp_path):
    path = LIB.without("measured").save(tmp_path / "lib.json")
    again = shapes.load(str(path))
    assert [s.step_noise for s in again.shapes] == [s.step_noise for s in
                                                    LIB.without("measured").shapes]
    assert len(again.sources()) == len(again.sharp().shapes) < len(again.sources(noisy=True))
    assert all(s.step_noise is None for s in again.sharp().shapes)


def test_a_library_saved_elsewhere_still_finds_the_table_files_beside_the_first(tmp_path):
    """A user's library names a table file beside it; the library written into another
    folder (a subset of it, say) names that file from there, so it loads with the same
    moves."""
    from pac_host.model.table import save_table

    (tmp_path / "lab").mkdir()
    save_table(measured_table(), tmp_path / "lab" / "ours.json")
    genes = SHARP[0].genes
    (tmp_path / "lab" / "lib.json").write_text(json.dumps({"format": shapes.FORMAT, "shapes": [
        {"turn_cycle": format_turn_cycle(genes), "table": "ours.json", "fitness": None},
        {"turn_cycle": format_turn_cycle(genes), "table": "shifted", "fitness": None}]}))
    first = shapes.load(str(tmp_path / "lab" / "lib.json"))
    (tmp_path / "elsewhere").mkdir()
    moved = shapes.load(str(first.save(tmp_path / "elsewhere" / "lib.json")))
    assert [s.table for s in moved.shapes][1] == "shifted"
    for a, b in zip(first.sources(), moved.sources(), strict=True):
        np.testing.assert_array_equal(a[1], b[1])


def test_a_turn_shift_is_a_relabelling_the_re_expression_undoes():
    """The shifted robot's rows are the measured table's one strength weaker: a sweep found on
    the one is the same path on the other with other gait ids."""
    src = parse_turn_cycle("29:7,21:11,17:3,7:21,3:1,21:13,12:4,7:1,2:8")  # 46 on shifted
    y = retarget(src, loop_table(shifted_table().rows), loop_table(measured_table().rows))
    assert _fitness(measured_table(), y[0])[0] == 46
    assert _fitness(measured_table(), src)[0] < 20  # the same genes are another walk


@pytest.mark.parametrize("target", ["shifted", "asymmetric", "library_on_changed"])
def test_the_compiled_re_expression_proposes_what_numpy_does(target, monkeypatch):
    """The numba beam step against the numpy reference, every library sweep re-expressed on
    three tables: the same turn cycles in the same order, errors equal but for rounding."""
    from pac_host.coverage import kernel as coverage_jit
    from pac_host.search import retarget as rt

    if not coverage_jit.AVAILABLE:
        pytest.skip("numba is not installed")
    table = shapes.table_of(target)
    moves = loop_table(table.rows, table.effects)
    for genes, source in LIB.sources():
        compiled = retarget(genes, source, moves)
        monkeypatch.setattr(coverage_jit, "AVAILABLE", False)
        reference = retarget(genes, source, moves)
        monkeypatch.setattr(coverage_jit, "AVAILABLE", True)
        assert len(compiled) == rt.BEAM and np.array_equal(compiled, reference)
    rng = np.random.default_rng(0)  # one step with ties in errors and in moves
    ends = np.exp(1j * rng.normal(size=(40, 2))) * rng.random((40, 2))
    ends[:, 1] /= np.abs(ends[:, 1])
    errors = np.sort(rng.random(40))
    errors[4] = errors[3]
    m = moves[1:, 1:].reshape(-1, 2)[:300]
    m[7] = m[5]
    walk = np.array([1 + 1j, np.exp(0.3j)])
    for cost in (np.zeros(len(m)), rng.random(len(m)) * 3):  # without and with a cost per move
        a = rt.beam_step(ends, errors, m, walk, 0.5, 64, cost)
        b = rt._compiled_step()(ends, errors, m, walk, 0.5, 64, cost)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert np.allclose(a[2], b[2], rtol=0, atol=1e-9) and np.allclose(a[3], b[3])
    assert not np.array_equal(a[1], rt.beam_step(ends, errors, m, walk, 0.5, 64,
                                                 np.zeros(len(m)))[1])


def test_the_path_carries_over_where_the_genes_do_not():
    """The library's sweeps on robots whose tables differ from theirs: the best re-expressed
    path scores well above the best of the same genes, on each (before any climb: 44 against
    4 on the shifted robot, 22 against 14 and 19 against 8 on the other two)."""
    for name, table in (("shifted", shifted_table()),
                        ("noisy_rows", robots.build("noisy_rows", 2)),
                        ("asymmetric", robots.build("asymmetric"))):
        lib = LIB.without(name)
        proposals = shapes.proposals(lib.sources(), loop_table(table.rows, table.effects), 200)
        assert len(proposals) > 5 * len(lib.shapes)
        raw = _fitness(table, np.stack([s.genes for s in lib.shapes])).max()
        moved = _fitness(table, proposals).max()
        assert moved >= raw + 8, (name, raw, moved)


@pytest.mark.parametrize("name", robots.ROBOTS)
def test_a_gait_cycle_of_the_re_expression_costs_path_error(name):
    """A sweep repeats its loop budget / L times, so of two expressions of a path about as
    close the shorter loop covers more: with the length cost the best start the library (less
    the robot's own sweeps) gives is a shorter loop and scores higher, on each robot of our own
    making (measured: 43 against 29 on asymmetric, 40 against 23 on outside_library)."""
    table = robots.build(name)
    sources = LIB.without(name).sources()

    def best_start(**cost):
        (x, score), *_ = shapes.starts(Objective(table.rows, 200, table.effects), sources,
                                       **cost)
        return int(_fitness(table, x)[0]), int(x[:, 1].sum())

    costed = best_start()  # the default cost
    free = best_start(length_cost=0.0)
    assert costed[0] >= free[0] + 3, (costed, free)
    assert costed[1] < free[1], (costed, free)


def test_without_leaves_out_the_sweeps_found_on_a_robot():
    rest = LIB.without("shifted")
    assert rest.shapes and all(s.found_on != "shifted" for s in rest.shapes)
    assert len(rest.shapes) == len(LIB.shapes) - sum(s.found_on == "shifted" for s in LIB.shapes)
    assert shapes.load("none").shapes == ()


def test_a_chain_starts_from_the_best_sweep_re_expressed_on_the_model():
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    best = _fitness(table, shapes.proposals(sources, loop_table(table.rows), 200)).max()
    with_lib, without = (Objective(table.rows, limit=3000) for _ in range(2))
    chain = Chain()
    chain.run(with_lib, np.random.default_rng(0), 50, shapes=sources)
    Chain().run(without, np.random.default_rng(0), 50)
    assert chain.starts == 1 and chain.shaped == with_lib.fingerprint()
    assert with_lib.fitness(with_lib.best_search_score) >= best
    assert best > without.fitness(without.best_search_score)
    assert Chain.from_json(json.loads(json.dumps(chain.to_json()))).to_json() == chain.to_json()


def test_starts_give_each_sources_best_proposal_best_first():
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    objective = Objective(table.rows)
    found = shapes.starts(objective, sources)
    assert len(found) == len(sources)  # the sources' sweeps differ: one start each
    scores = [s for _, s in found]
    assert scores == sorted(scores, reverse=True)
    best = _fitness(table, shapes.proposals(sources, loop_table(table.rows), 200)).max()
    assert objective.fitness(scores[0]) == best
    for genes, score in found:
        assert int(objective(genes[None])[0]) == score
    mine = [shapes.starts(Objective(table.rows), [src])[0][1] for src in sources]
    assert sorted(mine, reverse=True) == scores  # each is the best its own source proposes


def test_a_chains_restarts_climb_the_best_start_again_not_a_weaker_one(monkeypatch):
    # climbs from one start end in different basins; the best start's are the likeliest to
    # end high, so a restart on the same model climbs it again (docs/explanation/learning.md)
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    first = shapes.starts_by_source(Objective(table.rows), sources)

    def no_cga(*args, **kwargs):
        raise AssertionError("a CGA start while the library gave one")

    monkeypatch.setattr(local, "cga_start", no_cga)
    chain = Chain()
    objective = Objective(table.rows, limit=60_000)
    chain.run(objective, np.random.default_rng(0), 2, shapes=sources)  # restart after 2 kicks
    assert chain.starts >= 3  # restarted, each time from the best start
    genes, score, k = first[0]
    assert np.array_equal(chain.origin[0], genes) and chain.origin[1] == score
    assert chain.origin[2] == objective.fingerprint()
    assert chain.taken == [shapes.source_key(sources[k])]  # no other source taken
    assert [s for _, s, _ in chain.queue] == [s for _, s, _ in first[1:]]
    again = Chain.from_json(json.loads(json.dumps(chain.to_json())))
    assert again.to_json() == chain.to_json()
    # carried on on the same model it goes on restarting there, the queue untouched
    starts = chain.starts
    objective.limit = objective.evaluations + 60_000
    chain.run(objective, np.random.default_rng(1), 2, shapes=sources)
    assert chain.starts > starts and len(chain.queue) == len(first) - 1


def test_a_chain_carried_to_a_new_model_starts_from_sources_it_has_not_tried():
    # after each punctuation the model changes a little; restarting from the library's best
    # source every time would climb the same basin over and over
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    keys = [shapes.source_key(src) for src in sources]
    assert len(set(keys)) == len(keys)
    chain = Chain()
    chain.run(Objective(table.rows, limit=40_000), np.random.default_rng(0), 2, shapes=sources)
    first = list(chain.taken)
    assert len(first) == 1 and set(first) <= set(keys)  # its restarts climb that start again
    origin = chain.origin[0].copy()
    moved = table.rows + np.random.default_rng(1).normal(scale=0.05, size=table.rows.shape)
    objective = Objective(moved, limit=40_000)
    starts = chain.starts
    chain.run(objective, np.random.default_rng(1), 2, shapes=sources)
    assert chain.starts > starts  # restarted on the new model
    assert chain.taken[: len(first)] == first
    assert len(set(chain.taken)) == len(chain.taken)  # no source started from twice
    assert not {k for _, _, k in chain.queue} & set(chain.taken)
    # a restart there climbs the best start so far, re-scored, unless a fresh source starts
    # higher: the origin is on the new model, and it is the old one or a fresh source's start
    scored = Objective(moved)  # the same model, without the spent budget
    assert chain.origin[2] == objective.fingerprint() == scored.fingerprint()
    assert chain.origin[1] == int(scored(chain.origin[0][None])[0])
    if len(chain.taken) == len(first):
        assert np.array_equal(chain.origin[0], origin)
    else:
        assert chain.origin[1] > int(scored(origin[None])[0])
    again = Chain.from_json(json.loads(json.dumps(chain.to_json())))
    assert again.to_json() == chain.to_json()


def test_a_new_model_re_expresses_the_sources_already_taken_too():
    # a source taken early was expressed on an early, wrong model; re-expressed on a later
    # one it may start higher than the origin there (docs/explanation/learning.md, noisy_rows)
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    keys = [shapes.source_key(src) for src in sources]
    best = shapes.starts_by_source(Objective(table.rows), sources)[0]
    poor = parse_turn_cycle("12:14,3:10")
    chain = Chain(taken=list(keys), origin=(poor, 0, "an earlier model"), starts=1)
    objective = Objective(table.rows, limit=10_000)
    chain.run(objective, np.random.default_rng(0), 2, shapes=sources)
    assert chain.queue == []  # every source taken: none is queued again
    assert np.array_equal(chain.origin[0], best[0]) and chain.origin[1] == best[1]
    assert chain.origin[2] == objective.fingerprint()
    # an origin that starts higher than every re-expression stays, re-scored on the model
    good = parse_turn_cycle("29:7,21:11,17:3,7:21,3:1,21:13,12:4,7:1,2:8")
    chain = Chain(taken=list(keys), origin=(good, 0, "an earlier model"), starts=1)
    objective = Objective(table.rows, limit=10_000)
    chain.run(objective, np.random.default_rng(0), 2, shapes=sources)
    scored = int(Objective(table.rows)(good[None])[0])
    assert scored > best[1]
    assert np.array_equal(chain.origin[0], good) and chain.origin[1] == scored


def test_a_carried_chain_takes_a_sweep_only_if_it_beats_its_own_point():
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    poor = parse_turn_cycle("12:14,3:10")
    chain = Chain(poor, starts=1)
    objective = Objective(table.rows, limit=10_000)  # the proposals' evaluations and a little
    chain.run(objective, np.random.default_rng(1), 50, shapes=sources)
    assert objective.fitness(objective.best_search_score) >= 40  # the sweep took its place
    good = parse_turn_cycle("29:7,21:11,17:3,7:21,3:1,21:13,12:4,7:1,2:8")
    chain = Chain(good, starts=1)
    objective = Objective(table.rows, limit=10_000)
    chain.run(objective, np.random.default_rng(1), 50, shapes=sources)
    assert objective.fitness(objective.best_search_score) == 46  # its own point kept


def test_a_carried_find_moves_the_chains_point_but_restarts_climb_the_librarys_start():
    """A chain's find on the model before, given as ``carried``, takes the chain's point on
    the new model when it starts higher, but is not taken as a source: the origin its
    restarts climb is the library's best start. Given as a source, it became the origin, and
    every restart climbed the chain's own find again."""
    table = shifted_table()
    sources = LIB.without("shifted").sources()
    library_best = shapes.starts_by_source(Objective(table.rows), sources)[0]
    find = parse_turn_cycle("11:2,13:2,22:12,17:3,24:4,3:1,0:4,10:7,0:4")  # 48 on shifted
    found = [shapes.carried(find, table.rows)]
    find_start = shapes.starts(Objective(table.rows), found)[0]
    assert find_start[1] > library_best[1]
    poor = parse_turn_cycle("12:14,3:10")
    origins = {}
    for as_source in (False, True):
        chain = Chain(poor, starts=1)  # a point from another model
        objective = Objective(table.rows, limit=60_000)
        kw = {"shapes": sources + found} if as_source else {"shapes": sources,
                                                            "carried": found}
        chain.run(objective, np.random.default_rng(0), 2, **kw)
        assert objective.fitness(objective.best_search_score) >= 48  # the find was climbed
        assert (shapes.source_key(found[0]) in chain.taken) == as_source
        assert chain.starts > 1  # it restarted, from its origin
        origins[as_source] = chain.origin
    assert np.array_equal(origins[False][0], library_best[0])
    assert origins[False][1] == library_best[1]
    assert np.array_equal(origins[True][0], find_start[0])


def test_pal_puts_the_librarys_best_sweep_on_the_starting_model_in_its_population():
    cfg = pal.PALConfig(search="ils", search_evaluations=1000, shapes="builtin",
                        cga_population=16)
    rng = np.random.default_rng(0)
    state = pal.initial_state(measured_table(), rng, cfg)
    plain = pal.initial_state(measured_table(), np.random.default_rng(0),
                              pal.PALConfig(search="ils", search_evaluations=1000,
                                            cga_population=16))
    assert _fitness(measured_table(), state.cga_pop[0])[0] == 46  # the library's, re-expressed
    assert _fitness(measured_table(), plain.cga_pop[0])[0] < 30


def test_the_oracle_with_the_library_reaches_the_robots_best_sooner(tmp_path):
    """A short anytime PAL run (the oracle: the search on the robot's own table), with the
    library less the robot's own sweeps against without it."""
    from pac_host.experiments.experiment import ExperimentConfig, run_experiment

    lib = tmp_path / "lib.json"
    lib.write_text(json.dumps(LIB.without("shifted").to_json()))
    finals = {}
    for name in ("none", str(lib)):
        cfg = ExperimentConfig(
            seeds=2, generations=80, methods=("oracle",), initial_generations=20,
            optimum_runs=1, optimum_search="optimize", optimum_evaluations=20_000,
            pal=pal.PALConfig(search="ils", search_evaluations=20_000, shapes=name,
                              cga_population=32))
        s = run_experiment(tmp_path / name.replace("/", "_"), cfg, measured_table(),
                           shifted_table(), 1)
        finals[name] = [r["coverage"][-1] for r in s["runs"]]
    assert min(finals[str(lib)]) >= 40 > max(finals["none"]), finals


@pytest.mark.parametrize("content, message", [
    (None, "cannot read shapes file"),
    ("{", "is not JSON"),
    ('{"format": "other"}', "is not a pac-shapes/1 file"),
    ('{"format": "pac-shapes/1", "shapes": [{"turn_cycle": "1:2"}]}', "shape 0 needs"),
    ('{"format": "pac-shapes/1", "shapes": [{"turn_cycle": "1:99", "table": "measured"}]}',
     "shape 0"),
    ('{"format": "pac-shapes/1", "shapes": [{"turn_cycle": "1:2", "table": "nowhere.json"}]}',
     "shape 0"),
    ('{"format": "pac-shapes/1", "shapes": [{"turn_cycle": "1:2", "table": "measured", '
     '"step_noise": "lots"}]}', "shape 0: --step-noise takes CM,DEG"),
])
def test_a_bad_shapes_file_is_one_line_and_exit_2(tmp_path, content, message):
    path = tmp_path / "shapes.json"
    if content is not None:
        path.write_text(content)
    res = CliRunner().invoke(main, ["optimize", "--table", "shifted", "--evaluations", "1000",
                                    "--shapes", str(path)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.output


def test_the_paper_profile_takes_no_library(tmp_path):
    res = CliRunner().invoke(main, ["experiment", "--profile", "paper", "--shapes", "builtin",
                                    "--seeds", "1", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "--shapes needs an anytime profile" in res.output


def test_optimize_starts_from_the_library_unless_told_not_to(tmp_path):
    def run(*extra):
        res = CliRunner().invoke(main, ["optimize", "--table", "shifted", "--evaluations",
                                        "2000", "--seed", "0", *extra])
        assert res.exit_code == 0, res.output
        return int(next(ln for ln in res.output.splitlines()
                        if ln.startswith("fitness:")).split()[1])

    assert run() == 46 > run("--shapes", "none")


def test_evolve_takes_the_library_by_default_and_keeps_it_in_its_config(tmp_path):
    from pac_host.robot.evolve import EvolveConfig, load_config

    assert EvolveConfig().shapes == "none"  # a run saved before the library had none
    assert EvolveConfig(search="ils", search_evaluations=10, shapes="builtin").pal().shapes \
        == "builtin"
    out = tmp_path / "run"
    res = CliRunner().invoke(main, ["evolve", "--out", str(out), "--generations", "20",
                                    "--interval", "20", "--cga-population", "16",
                                    "--initial-generations", "5", "--search-evaluations",
                                    "2000", "--budget", "100"])
    assert res.exit_code == 0, res.output
    assert load_config(out).shapes == "builtin"
    # the default profile's search settings, kept for a resume
    assert load_config(out).library_restarts and load_config(out).finish_moves
    assert load_config(out).refine_effects
    bad = CliRunner().invoke(main, ["evolve", "--out", str(tmp_path / "bad"), "--shapes",
                                    str(tmp_path / "missing.json")])
    assert bad.exit_code == 2 and "cannot read shapes file" in bad.output


def test_a_chain_saved_before_sources_were_remembered_still_resumes():
    doc = {"x": None, "stale": 0, "queue": [[[[12, 3], [3, 1]], 700]]}
    chain = Chain.from_json(doc)
    assert chain.taken == [] and chain.queue[0][1:] == (700, None) and chain.origin is None
    assert Chain.from_json(chain.to_json()).to_json() == chain.to_json()
    with pytest.raises(TypeError):  # an entry without its score (a state then says malformed)
        Chain.from_json({"queue": [[[[12, 3]]]]})
    with pytest.raises(TypeError):  # an origin without the model it was scored on
        Chain.from_json({"origin": [[[12, 3]], 700]})


def test_each_source_s_re_expression_is_remembered_and_not_changed_by_callers():
    """The chains of a punctuation re-express the library on the same model beside sources of
    their own: a source already re-expressed on a target is not re-expressed again, a caller
    changing what it was given changes nothing remembered, and another target is computed
    afresh."""
    srcs = shapes.load("builtin").sources()[:3]
    target = loop_table(shifted_table().rows)
    shapes._MEMO.clear()
    pop, _ = shapes._proposals(srcs, target, 200)
    want = pop.copy()
    pop[:] = 0
    assert len(shapes._MEMO) == 3
    again, _ = shapes._proposals(srcs, target, 200)
    assert len(shapes._MEMO) == 3 and np.array_equal(again, want)
    own = shapes.carried(want[0], measured_table().rows)
    shared, owner = shapes._proposals(srcs[:2] + [own], target, 200)
    assert len(shapes._MEMO) == 4  # only the new source was re-expressed
    shapes._MEMO.clear()
    fresh, fresh_owner = shapes._proposals(srcs[:2] + [own], target, 200)
    assert np.array_equal(shared, fresh) and np.array_equal(owner, fresh_owner)
    other, _ = shapes._proposals(srcs, loop_table(measured_table().rows), 200)
    assert len(shapes._MEMO) == 6 and not np.array_equal(other, want)
