"""The compiled coverage kernel against the numpy simulator, the reference: value for value."""

from __future__ import annotations

import numpy as np
import pytest

from pac_host.coverage import START_POSE, expand, search_score, simulate
from pac_host.coverage import kernel as coverage_jit
from pac_host.coverage.engine import _Runner
from pac_host.model import measured_table, parse_effect, shifted_table, step_moves
from pac_host.model.effects import ParamSpec, register_effect
from pac_host.model.effects_module import forget_user_effects
from pac_host.model.kinematics import complex_moves
from pac_host.search import cga

pytestmark = pytest.mark.skipif(not coverage_jit.AVAILABLE, reason="numba not installed")
FIGURES = ("blocks_covered", "blocks_covered_once", "fitness", "repeat_visits", "reached_at")


def _population(rng: np.random.Generator, n: int) -> np.ndarray:
    pop = cga.random_population(rng, n)
    short = rng.random(pop.shape[:2]) < 0.5  # short genes too: loops that repeat many times
    pop[..., 1] = np.where(short, pop[..., 1] // 8, pop[..., 1])
    pop[:8, :, 1] = 0  # turn cycles that stand still
    pop[8:16, 1:, 1] = 0  # a single gene
    return pop


def _same(a, b) -> None:
    for f in FIGURES:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


@pytest.mark.parametrize("budget", [0, 1, 37, 200, 450])
def test_kernel_equals_numpy_on_random_turn_cycles(budget):
    rng = np.random.default_rng(budget)
    pop = _population(rng, 3000)
    for rows in (measured_table().rows, shifted_table().rows,
                 measured_table().rows + rng.normal(0, 0.8, (32, 3))):
        _same(simulate(rows, pop, budget, kernel="numba"),
              simulate(rows, pop, budget, kernel="numpy"))


def test_kernel_equals_numpy_on_many_tables_and_with_effects():
    rng = np.random.default_rng(1)
    pop = _population(rng, 40)
    models = measured_table().rows + rng.normal(0, 0.6, (50, 32, 3))
    _same(simulate(models, pop, 200, kernel="numba"), simulate(models, pop, 200, kernel="numpy"))
    effects = [parse_effect(s) for s in ("turn_shift:k=2", "stride_scale:a=1.3",
                                         "yaw_bias:delta=-0.7", "lateral_slip:gamma=0.05",
                                         "floor_slope:s=0.8,theta=200")]
    pop = _population(rng, 2000)
    _same(simulate(measured_table().rows, pop, 200, effects, kernel="numba"),
          simulate(measured_table().rows, pop, 200, effects, kernel="numpy"))


def test_auto_uses_numpy_where_the_kernel_does_not_apply():
    pop = _population(np.random.default_rng(2), 30)
    for seq in (["transition:alpha=0.3", "transition:alpha=0.5"],
                ["battery_sag:beta=0.002", "battery_sag:beta=0.001"]):
        with pytest.raises(ValueError):
            simulate(measured_table().rows, pop, 100, [parse_effect(e) for e in seq],
                     kernel="numba")
    with pytest.raises(ValueError):
        simulate(measured_table().rows, pop, 100, keep_paths=True, kernel="numba")
    kept = simulate(measured_table().rows, pop, 100, keep_paths=True)
    assert kept.poses is not None
    _same(kept, simulate(measured_table().rows, pop, 100, kernel="numba"))


@pytest.mark.parametrize("budget", [0, 5, 60, 200, 450])
def test_kernel_equals_numpy_on_batches_that_share_their_first_genes(budget):
    """A search's batch changes one gene and keeps those before it, its repetitions in order:
    the kernel starts each path where it parts from the one before. Whole neighbourhoods of
    each gene and paired repetition changes, on one and on many tables, with drift."""
    from pac_host.search.neighbours import neighbours, pair_neighbours

    rng = np.random.default_rng(budget + 7)
    models = measured_table().rows + rng.normal(0, 0.6, (5, 32, 3))
    drift = [parse_effect("floor_slope:s=0.8,theta=200")]
    for x in _population(rng, 28)[[0, 8, 16, 17, 18, 19]]:
        for j in range(9):
            batch = neighbours(x, 10**6, only=j)
            if not len(batch):
                continue
            batch = np.concatenate([x[None], batch, pair_neighbours(x, 10**6)])
            _same(simulate(shifted_table().rows, batch, budget, kernel="numba"),
                  simulate(shifted_table().rows, batch, budget, kernel="numpy"))
            _same(simulate(models, batch[:70], budget, drift, kernel="numba"),
                  simulate(models, batch[:70], budget, drift, kernel="numpy"))


def _transition_population(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random turn cycles, and ones where a gait id follows itself (no change, no blend):
    in the next gene, across a gene without repetitions, and from the last gene to the first."""
    pop = _population(rng, n)
    pop[16:40, 1, 0] = pop[16:40, 0, 0]
    pop[40:64, 1, 1] = 0
    pop[40:64, 2, 0] = pop[40:64, 0, 0]
    pop[64:88, 8, 0] = pop[64:88, 0, 0]
    pop[88:112, 0, 1] = 0  # the loop's first gene skipped: it starts on the second
    return pop


TRANSITION_EFFECTS = [
    [],
    ["turn_shift:k=2", "yaw_bias:delta=-0.7"],
    ["floor_slope:s=0.8,theta=200"],
    # listed out of order: the effects run in the canonical order whatever order they come in
    ["floor_slope:s=-0.6,theta=40", "lateral_slip:gamma=0.05", "turn_shift:k=-3",
     "stride_scale:a=1.2", "turn_scale:c=0.9"],
]


@pytest.mark.parametrize("alpha", [0.0, 0.05, 0.4, 0.75, 1.0])
@pytest.mark.parametrize("others", range(len(TRANSITION_EFFECTS)))
def test_kernel_equals_numpy_with_transition(alpha, others):
    """The transition blends the first gait cycle after a change of gait id with the gait
    before it; the kernel looks the blend up per pair of ids, on one and on many tables."""
    rng = np.random.default_rng(int(alpha * 100) + 10 * others)
    effects = [parse_effect(f"transition:alpha={alpha}")]
    effects += [parse_effect(e) for e in TRANSITION_EFFECTS[others]]
    if others % 2:
        effects.reverse()
    pop = _transition_population(rng, 1500)
    for budget in (1, 2, 200):
        _same(simulate(shifted_table().rows, pop, budget, effects, kernel="numba"),
              simulate(shifted_table().rows, pop, budget, effects, kernel="numpy"))
    models = measured_table().rows + rng.normal(0, 0.6, (6, 32, 3))
    _same(simulate(models, pop[:300], 200, effects, kernel="numba"),
          simulate(models, pop[:300], 200, effects, kernel="numpy"))
    _same(simulate(models, pop[:3], 200, effects, kernel="numba"),  # few changes of gait id
          simulate(models, pop[:3], 200, effects, kernel="numpy"))


def test_transition_changes_the_figures_and_auto_runs_it_in_the_kernel(monkeypatch):
    """The blend is not a no-op the comparison could pass by (the figures move with alpha),
    and ``kernel="auto"`` takes the compiled path for it."""
    pop = _transition_population(np.random.default_rng(5), 2000)
    rows = shifted_table().rows
    plain = simulate(rows, pop, 200, kernel="numpy").score()
    for alpha in (0.3, 1.0):
        blended = simulate(rows, pop, 200, [parse_effect(f"transition:alpha={alpha}")],
                           kernel="numpy").score()
        assert (blended != plain).mean() > 0.2
    calls = []
    score_paths = coverage_jit.score_paths
    monkeypatch.setattr(coverage_jit, "score_paths",
                        lambda *a, **k: calls.append(1) or score_paths(*a, **k))
    effects = [parse_effect("transition:alpha=0.3"), parse_effect("yaw_bias:delta=0.5")]
    _same(simulate(rows, pop, 200, effects), simulate(rows, pop, 200, effects, kernel="numpy"))
    assert calls == [1]
    simulate(rows, pop, 200, [*effects, parse_effect("battery_sag:beta=0.001")])
    assert calls == [1]  # with battery_sag the kernel takes moves per step: score_tabulated


def test_transition_table_holds_every_change_and_the_numpy_paths_moves_bit_for_bit():
    """The pairs cover every change of gait id the paths make, and each tabulated move is the
    one the numpy path converts from ``step_moves``' blend, to the last bit (figures are
    integers and rarely show a last-bit change)."""
    rng = np.random.default_rng(9)
    pop = _transition_population(rng, 400)
    ids, still = expand(pop, 300)
    ids = ids[~still]
    change = ids[:, 1:] != ids[:, :-1]
    walked = set(zip(ids[:, :-1][change].tolist(), ids[:, 1:][change].tolist(), strict=True))
    pairs = coverage_jit.transition_pairs(pop)
    assert walked <= set(map(tuple, pairs.tolist()))
    assert len(pairs) > 200
    rows = measured_table().rows + rng.normal(0, 0.6, (3, 32, 3))
    effects = tuple(parse_effect(e) for e in ("lateral_slip:gamma=0.05", "transition:alpha=0.37",
                                              "turn_shift:k=2", "yaw_bias:delta=-0.7"))
    for table in (rows, rows[0]):
        run = _Runner(table, 300, effects, np.array(START_POSE), False)
        got_pairs, blended = run.transition_moves(pop)
        np.testing.assert_array_equal(got_pairs, pairs)
        walks = np.broadcast_to(pairs, table.shape[:-2] + pairs.shape)
        body, _ = step_moves(table, walks, effects)  # two gait cycles: pair[0], then pair[1]
        np.testing.assert_array_equal(blended, complex_moves(body[..., 1, :]).reshape(-1, 2))


@pytest.mark.parametrize("budget", [3, 60, 200])
def test_kernel_equals_numpy_with_transition_on_batches_that_share_their_first_genes(budget):
    """A path resumes where it parts from the one before it: the gait id walked there decides
    whether its next gait cycle blends. Single-gene neighbourhoods, on one and many tables."""
    from pac_host.search.neighbours import neighbours

    rng = np.random.default_rng(budget + 11)
    models = measured_table().rows + rng.normal(0, 0.6, (3, 32, 3))
    pop = _transition_population(rng, 120)
    for alpha, extra in ((0.4, []), (1.0, ["turn_shift:k=1", "floor_slope:s=0.8,theta=200"])):
        effects = [parse_effect(f"transition:alpha={alpha}")] + [parse_effect(e) for e in extra]
        for x in pop[[0, 8, 16, 20, 40, 64, 88, 112, 113]]:
            batch = np.concatenate([x[None], neighbours(x, budget)])
            _same(simulate(shifted_table().rows, batch, budget, effects, kernel="numba"),
                  simulate(shifted_table().rows, batch, budget, effects, kernel="numpy"))
            _same(simulate(models, batch[::7], budget, effects, kernel="numba"),
                  simulate(models, batch[::7], budget, effects, kernel="numpy"))


SAG_EFFECTS = [
    [],
    ["transition:alpha=0.3"],
    ["floor_slope:s=0.8,theta=200"],
    # listed out of order: the effects run in the canonical order whatever order they come in
    ["floor_slope:s=-0.6,theta=40", "transition:alpha=0.3", "turn_shift:k=2",
     "yaw_bias:delta=-0.7"],
]


@pytest.mark.parametrize("beta", [0.0, 0.0003, 0.002, 0.006, 0.1])
@pytest.mark.parametrize("others", range(len(SAG_EFFECTS)))
def test_kernel_equals_numpy_with_battery_sag(beta, others):
    """Battery sag scales each gait cycle's move by 1 - beta i at step i of the run, down to
    nothing (beta 0.006 reaches it within 200 steps, 0.1 within 10): the kernel looks the move
    up per step, alone, after a transition's blend and with a world drift; on one and on many
    tables, with short loops that repeat many times."""
    rng = np.random.default_rng(int(beta * 10**4) + 100 * others)
    effects = [parse_effect(f"battery_sag:beta={beta}")]
    effects += [parse_effect(e) for e in SAG_EFFECTS[others]]
    if others % 2:
        effects.reverse()
    pop = _transition_population(rng, 1500)
    pop[1000:1300, :, 1] //= 3
    for budget in (1, 2, 37, 200):
        _same(simulate(shifted_table().rows, pop, budget, effects, kernel="numba"),
              simulate(shifted_table().rows, pop, budget, effects, kernel="numpy"))
    models = measured_table().rows + rng.normal(0, 0.6, (6, 32, 3))
    _same(simulate(models, pop[:300], 200, effects, kernel="numba"),
          simulate(models, pop[:300], 200, effects, kernel="numpy"))
    _same(simulate(models, pop[:3], 200, effects, kernel="numba"),
          simulate(models, pop[:3], 200, effects, kernel="numpy"))


@pytest.mark.parametrize("effects", [("battery_sag:beta=0.002",),
                                     ("battery_sag:beta=0.006", "transition:alpha=0.3"),
                                     ("floor_slope:s=0.5,theta=60", "battery_sag:beta=0.001",
                                      "transition:alpha=0.6")])
def test_a_scorer_with_battery_sag_runs_the_kernel_batch_after_batch(effects, monkeypatch):
    """A scorer keeps the moves it tabulated per step and fills in those of new gait ids and
    changes of gait id as batches bring them: each batch's scores are the numpy simulator's,
    value for value, from the kernel, over random turn cycles, short loops and a search's
    single-gene neighbourhoods (which share their first steps)."""
    from pac_host.coverage import Scorer
    from pac_host.search.neighbours import neighbours

    effs = tuple(parse_effect(e) for e in effects)
    rows, rng = shifted_table().rows, np.random.default_rng(12)
    calls = []
    score_tabulated = coverage_jit.score_tabulated
    monkeypatch.setattr(coverage_jit, "score_tabulated",
                        lambda *a, **k: calls.append(1) or score_tabulated(*a, **k))
    scorer = Scorer(rows, 200, effs, (60.0, 20.0, 80.0))
    pop = _transition_population(rng, 200)
    batches = [pop[:1], pop[1:40], pop[40:200] // np.array([1, 3])]
    batches += [np.concatenate([x[None], neighbours(x, 200)]) for x in pop[[0, 20, 64, 120]]]
    for batch in batches:
        want = simulate(rows, batch, 200, effs, (60.0, 20.0, 80.0), kernel="numpy")
        got = scorer.both(batch)
        assert (got[1] == want.score()).all()
        np.testing.assert_array_equal(got[0], search_score(want.fitness, want.reached_at,
                                                           want.repeat_visits, 200))
    assert len(calls) == len(batches)


def test_battery_sag_is_compiled_and_its_step_moves_are_the_numpy_paths_bit_for_bit():
    """The runner compiles battery_sag (alone, after a transition, with a drift), tabulates
    the step factor up to where it reaches 0, and each tabulated move is the one the numpy
    path converts from ``step_moves``, to the last bit; too large a table runs in numpy."""
    rng = np.random.default_rng(13)
    start = np.array(START_POSE)
    rows = measured_table().rows + rng.normal(0, 0.6, (3, 32, 3))
    for extra in ([], ["transition:alpha=0.3"], ["floor_slope:s=0.8,theta=200"],
                  ["transition:alpha=0.3", "floor_slope:s=0.8,theta=200", "turn_shift:k=2"]):
        effects = tuple(parse_effect(e) for e in ["battery_sag:beta=0.006", *extra])
        for table in (rows, rows[0]):
            run = _Runner(table, 200, effects, start, False)
            assert run.compiled
            assert len(run.factor) == 168  # 1 - 0.006 i reaches 0 at step 167, of 200
            pop = _transition_population(rng, 120)
            run.tabulate_steps(pop)
            ids = np.unique(pop[..., 0][pop[..., 1] > 0])
            walks = np.broadcast_to(ids[:, None], table.shape[:-2] + (len(ids), 200))
            body, _ = step_moves(table, walks, effects)  # each id walked throughout
            want = complex_moves(body[..., :168, :]).reshape(-1, len(ids), 168, 2)
            np.testing.assert_array_equal(run._disp[:, ids], want[..., 0])
            np.testing.assert_array_equal(run._rot[:, ids], want[..., 1])
            assert (body[..., 167:, :] == body[..., 167:168, :]).all()  # the last for later
            if extra and extra[0].startswith("transition"):
                pairs = coverage_jit.transition_pairs(pop)
                walks = np.broadcast_to(pairs[:, None, :], (len(pairs), 100, 2)).reshape(
                    len(pairs), 200)  # prev, gait, prev, gait ...: a change at every step
                walks = np.broadcast_to(walks, table.shape[:-2] + walks.shape)
                body, _ = step_moves(table, walks, effects)
                slot = run._slots[pairs[:, 0] * 32 + pairs[:, 1]]
                want = complex_moves(body[..., 1:168:2, :]).reshape(-1, len(pairs), 84, 2)
                np.testing.assert_array_equal(run._blend_disp[:, slot, 1:168:2], want[..., 0])
                np.testing.assert_array_equal(run._blend_rot[:, slot, 1:168:2], want[..., 1])
    assert _Runner(rows[0], 200, (parse_effect("battery_sag:beta=0.0001"),), start,
                   False).compiled
    many = measured_table().rows + np.zeros((200, 32, 3))
    effects = (parse_effect("battery_sag:beta=0.0001"), parse_effect("transition:alpha=0.3"))
    assert not _Runner(many, 200, effects, start, False).compiled  # 200 x 200 x 1056 entries
    assert _Runner(many[:30], 200, effects, start, False).compiled


def test_battery_sag_changes_the_figures_and_auto_runs_it_in_the_kernel(monkeypatch):
    """The sag is not a no-op the comparison could pass by, and ``kernel="auto"`` (and a
    scorer) take the compiled path for it."""
    pop = _transition_population(np.random.default_rng(14), 2000)
    rows = shifted_table().rows
    plain = simulate(rows, pop, 200, kernel="numpy").score()
    for beta in (0.002, 0.006):
        sag = simulate(rows, pop, 200, [parse_effect(f"battery_sag:beta={beta}")],
                       kernel="numpy").score()
        assert (sag != plain).mean() > 0.2
    calls = []
    score_tabulated = coverage_jit.score_tabulated
    monkeypatch.setattr(coverage_jit, "score_tabulated",
                        lambda *a, **k: calls.append(1) or score_tabulated(*a, **k))
    effects = [parse_effect("battery_sag:beta=0.002"), parse_effect("yaw_bias:delta=0.5")]
    _same(simulate(rows, pop, 200, effects), simulate(rows, pop, 200, effects, kernel="numpy"))
    assert calls == [1]


@pytest.fixture
def user_effect():
    register_effect("halve", [ParamSpec("f", 0.0, 1.0, neutral=1.0)],
                    lambda body, ctx, f: np.where(ctx.prev_ids[..., None] >= 0, f * body, body))
    yield
    forget_user_effects()


def test_a_user_defined_effect_runs_in_numpy(user_effect, monkeypatch):
    pop = _population(np.random.default_rng(4), 200)
    rows = shifted_table().rows
    for effects in ([parse_effect("halve:f=0.5")],
                    [parse_effect("transition:alpha=0.3"), parse_effect("halve:f=0.5")]):
        with pytest.raises(ValueError):
            simulate(rows, pop, 100, effects, kernel="numba")
        monkeypatch.setattr(coverage_jit, "score_paths", None)  # the kernel is not called
        auto = simulate(rows, pop, 100, effects)
        monkeypatch.undo()
        _same(auto, simulate(rows, pop, 100, effects, kernel="numpy"))
        assert (auto.score() != simulate(rows, pop, 100, effects[:-1]).score()).any()


@pytest.mark.parametrize("effects", [(), ("turn_shift:k=1",), ("transition:alpha=0.4",),
                                     ("battery_sag:beta=0.002",),
                                     ("floor_slope:s=0.5,theta=60", "yaw_bias:delta=1")])
def test_a_scorer_gives_simulates_scores_batch_after_batch(effects):
    """A search's scorer sets a model up once and scores many batches: each batch's scores are
    simulate's, value for value, whichever kernel the model's effects allow (and none for an
    empty batch)."""
    from pac_host.coverage import Scorer

    effs = tuple(parse_effect(e) for e in effects)
    rows, rng = shifted_table().rows, np.random.default_rng(6)
    scorer = Scorer(rows, 150, effs, (60.0, 20.0, 80.0))
    for size in (0, 1, 37, 300):
        pop = cga.random_population(rng, size)
        pop[: size // 2, :, 1] //= 5
        want = simulate(rows, pop, 150, effs, (60.0, 20.0, 80.0), kernel="numpy").score()
        assert (scorer(pop) == want).all()


def test_auto_walks_a_few_turn_cycles_on_many_tables_with_battery_sag_in_numpy(monkeypatch):
    """Tabulating a sag's moves per step costs more than numpy walking a model GA's three
    tests on many tables: ``kernel="auto"`` leaves those to numpy, whose figures they are."""
    rng = np.random.default_rng(15)
    models = measured_table().rows + rng.normal(0, 0.5, (64, 32, 3))
    pop = _population(rng, 40)[16:19]
    effects = [parse_effect("battery_sag:beta=0.002")]
    monkeypatch.setattr(coverage_jit, "score_tabulated", None)  # the kernel is not called
    _same(simulate(models, pop, 200, effects), simulate(models, pop, 200, effects,
                                                         kernel="numpy"))
