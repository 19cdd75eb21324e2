"""Step noise in the robots the project simulates: gait-table files, the experiment's robot and
`simulate --step-noise --walks`. Zero noise is today's result value for value."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.coverage import expand, parse_turn_cycle, simulate
from pac_host.coverage.walks import noisy_walks, walk_many
from pac_host.errors import InputError
from pac_host.learning.pal import SimulatedRobot
from pac_host.model import Effect, load_table, load_with_effects, save_table, shifted_table
from pac_host.model.effects import step_moves
from pac_host.model.kinematics import moves_between
from pac_host.model.step_noise import NONE, StepNoise, noisy_step_moves, parse_step_noise
from pac_host.search import cga

TC = "12:14,3:10,12:3,19:10"
EFFECTS = (Effect("transition", {"alpha": 0.3}), Effect("floor_slope", {"s": 0.4, "theta": 30}))


def _run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def _state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


def per_cycle() -> StepNoise:
    """Turns noisier than straights: 0.2 cm / 0.5 deg on straights, 0.6 cm / 3 deg on turns."""
    sd = np.tile([0.6, 0.6, 3.0], (32, 1))
    sd[[15, 31]] = [0.2, 0.2, 0.5]
    return StepNoise(sd)


# --- gait-table files --------------------------------------------------------------------

@pytest.mark.parametrize("noise", [parse_step_noise("0.3,1"), per_cycle()])
def test_a_table_file_carries_its_step_noise(tmp_path, noise):
    table = shifted_table().with_step_noise(noise)
    save_table(table, tmp_path / "t.json")
    back = load_table(tmp_path / "t.json")
    assert back.step_noise == noise and np.array_equal(back.rows, table.rows)
    assert back.with_rows(back.rows * 2).step_noise == noise
    assert back.with_effects(EFFECTS).step_noise == noise


def test_a_table_without_step_noise_is_written_as_before(tmp_path):
    save_table(shifted_table(), tmp_path / "t.json")
    assert "step_noise" not in json.loads((tmp_path / "t.json").read_text())
    assert load_table(tmp_path / "t.json").step_noise.is_zero()


def test_step_noise_on_the_command_line_overrides_the_files(tmp_path):
    save_table(shifted_table().with_step_noise(per_cycle()), tmp_path / "t.json")
    spec = str(tmp_path / "t.json")
    assert load_with_effects(spec).step_noise == per_cycle()
    assert load_with_effects(spec, (), "0.5,2").step_noise == parse_step_noise("0.5,2")
    assert load_with_effects(spec, (), "none").step_noise.is_zero()


def test_table_export_writes_step_noise_and_show_prints_it(tmp_path):
    path = tmp_path / "t.json"
    assert _run(["table", "export", str(path), "--table", "shifted",
                 "--step-noise", "0.3,1"]).exit_code == 0
    assert json.loads(path.read_text())["step_noise"] == {"F": 0.3, "T": 0.3, "dH": 1.0}
    assert "step noise: 0.3,1" in _run(["table", "show", "--table", str(path)]).output


@pytest.mark.parametrize("value, words", [
    ({"F": -1, "T": 0, "dH": 0}, "must be >= 0"),
    ({"F": 0.3, "T": 0.3}, "missing dH"),
    ({"F": "x", "T": 0, "dH": 0}, "must be numbers"),
    ({"F": 0.3, "T": 0.3, "dH": 500}, "at most"),
    ([0.3, 1], "must be an object"),
])
def test_a_bad_step_noise_in_a_table_file_is_one_line(tmp_path, value, words):
    doc = shifted_table().to_json()
    doc["step_noise"] = value
    (tmp_path / "t.json").write_text(json.dumps(doc))
    res = CliRunner().invoke(main, ["table", "show", "--table", str(tmp_path / "t.json")])
    assert res.exit_code == 2 and words in res.output and "step_noise" in res.output
    assert len(res.output.strip().splitlines()) == 1


# --- the one place a move is drawn ---------------------------------------------------------

def test_zero_noise_draws_nothing_and_moves_as_step_moves():
    rows, ids = shifted_table().rows, np.array([[12, 3, 3, 19, 12]])
    rng = np.random.default_rng(1)
    before = _state(rng)
    body, world = noisy_step_moves(rows, ids, EFFECTS, NONE, rng)
    want_body, want_world = step_moves(rows, ids, EFFECTS)
    assert np.array_equal(body, want_body) and np.array_equal(world, want_world)
    assert _state(rng) == before


def test_drawn_step_errors_have_the_configured_deviations():
    noise = per_cycle()
    rows = shifted_table().rows
    ids = np.tile(np.array([15, 3, 31, 19]), 20_000)  # straights and turns, 20,000 each
    body, _ = noisy_step_moves(rows, ids, (), noise, np.random.default_rng(7))
    err = body - step_moves(rows, ids)[0]
    for gid in (15, 3, 31, 19):
        e = err[ids == gid]
        np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=0.05)
        np.testing.assert_allclose(e.std(axis=0), noise.sd[gid], rtol=0.03)
    assert np.abs(np.corrcoef(err.T) - np.eye(3)).max() < 0.03  # components independent


# --- walks ---------------------------------------------------------------------------------

def test_noise_free_walks_are_simulates_figures_and_paths():
    pop = cga.random_population(np.random.default_rng(3), 200)
    for effects in ((), EFFECTS):
        want = simulate(shifted_table().rows, pop, 200, effects, keep_paths=True)
        got = noisy_walks(shifted_table().rows, pop, 200, effects, NONE, None, keep_paths=True)
        for f in ("blocks_covered", "blocks_covered_once", "fitness", "repeat_visits",
                  "reached_at", "blocks", "poses"):
            assert np.array_equal(getattr(got, f), getattr(want, f)), f


def test_noisy_walks_differ_and_repeat_from_the_seed():
    genes, noise = parse_turn_cycle(TC), parse_step_noise("0.3,1")

    def walk(seed: int):
        return walk_many(shifted_table().rows, genes, 300, 200, (), noise,
                         np.random.default_rng(seed), keep=300)

    a, pa = walk(0)
    b, pb = walk(0)
    c, pc = walk(1)
    assert np.array_equal(pa, pb) and np.array_equal(a.fitness, b.fitness)
    assert not np.array_equal(pa, pc)
    assert len({p.tobytes() for p in pa}) == 300  # every walk its own path
    exact = simulate(shifted_table().rows, genes, 200, keep_paths=True).poses[0]
    assert np.abs(pa[:, -1, :2] - exact[-1, :2]).max() > 5  # the paths wander
    # the walked moves are the table's plus errors of the configured deviations
    ids, _ = expand(genes[None], 200)
    err = moves_between(pa) - shifted_table().rows[ids[0]]
    np.testing.assert_allclose(err.mean(axis=(0, 1)), 0.0, atol=0.02)
    np.testing.assert_allclose(err.std(axis=(0, 1)), [0.3, 0.3, 1.0], rtol=0.03)


def test_walks_in_chunks_are_one_stream(monkeypatch):
    from pac_host.coverage import walks

    args = (shifted_table().rows, parse_turn_cycle(TC), 50, 200, (), parse_step_noise("0.3,1"))
    whole, _ = walk_many(*args, np.random.default_rng(5))
    monkeypatch.setattr(walks, "CHUNK_STEPS", 201 * 7)  # chunks of 7 walks
    chunked, _ = walk_many(*args, np.random.default_rng(5))
    assert np.array_equal(whole.fitness, chunked.fitness)


# --- the experiment's robot ----------------------------------------------------------------

def test_a_noise_free_robot_is_simulate_and_draws_nothing():
    tests = cga.random_population(np.random.default_rng(4), 3)
    rng = np.random.default_rng(0)
    before = _state(rng)
    got = SimulatedRobot(shifted_table(), rng=rng).run_tests(tests)
    want = simulate(shifted_table().rows, tests, keep_paths=True)
    assert [r.fitness for r in got] == want.fitness.tolist()
    assert all(np.array_equal(r.poses, p) for r, p in zip(got, want.poses, strict=True))
    assert _state(rng) == before


def test_a_noisy_robot_walks_each_test_afresh_from_its_seed():
    table = shifted_table().with_step_noise(parse_step_noise("0.3,1"))
    tests = np.stack([parse_turn_cycle(TC)] * 2)
    a = SimulatedRobot(table, rng=np.random.default_rng(2)).run_tests(tests)
    b = SimulatedRobot(table, rng=np.random.default_rng(2)).run_tests(tests)
    assert all(np.array_equal(x.poses, y.poses) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0].poses, a[1].poses)  # the same turn cycle, another walk
    exact = simulate(table.rows, tests[0], keep_paths=True).poses[0]
    assert not np.allclose(a[0].poses, exact)
    with pytest.raises(ValueError, match="Generator"):
        SimulatedRobot(table)


def test_experiment_step_noise_draws_from_the_seed_not_the_jobs(tmp_path):
    from pac_host.experiments.experiment import ExperimentConfig, pal_run
    from pac_host.learning.config import PALConfig
    from pac_host.model import measured_table
    from pac_host.search.cga import random_population

    cfg = ExperimentConfig(seeds=1, generations=40, initial_generations=0,
                           pal=PALConfig())
    pop = random_population(np.random.default_rng(0), cfg.pal.cga_config().population)
    quiet = shifted_table()
    noisy = quiet.with_step_noise(parse_step_noise("0.5,2"))
    runs = [pal_run(measured_table(), actual, 0, "partial", pop, cfg, None)
            for actual in (quiet, quiet.with_step_noise(NONE), noisy, noisy)]
    assert runs[0] == runs[1]  # zero noise: today's run
    assert runs[2] == runs[3]  # the noise repeats from the seed alone
    assert runs[2]["final_model"] != runs[0]["final_model"]  # the learner saw a noisy robot


def test_experiment_step_noise_option(tmp_path):
    small = ["--seeds", "1", "--generations", "40", "--initial-generations", "20",
             "--optimum-runs", "1", "--optimum-evaluations", "20000",
             "--search-evaluations", "2000", "--methods", "partial", "--quiet"]
    res = _run(["experiment", *small, "--out", str(tmp_path / "n"), "--step-noise", "0.5,2"])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "n" / "summary.json").read_text())
    assert summary["actual"]["step_noise"] == {"F": 0.5, "T": 0.5, "dH": 2.0}
    res = CliRunner().invoke(main, ["experiment", *small, "--out", str(tmp_path / "b"),
                                    "--step-noise", "-1,2"])
    assert res.exit_code == 2 and "must be >= 0" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "b").exists()


# --- simulate ------------------------------------------------------------------------------

@pytest.mark.parametrize("extra", [[], ["--placement-error", "0.5,1", "--walks", "50"],
                                   ["--json"]])
def test_simulate_without_step_noise_is_unchanged(extra):
    base = _run(["simulate", "--table", "shifted", "--turn-cycle", TC, *extra])
    for zero in ("none", "0", "0,0"):
        res = _run(["simulate", "--table", "shifted", "--turn-cycle", TC, *extra,
                    "--step-noise", zero])
        assert res.exit_code == 0 and res.output == base.output


def test_simulate_walks_report_the_spread_and_repeat_from_the_seed():
    tc = "12:14,3:10"  # fitness 6 from the exact start, 5 to 7 walked with noise
    args = ["simulate", "--table", "shifted", "--turn-cycle", tc, "--step-noise", "0.3,1",
            "--walks", "400", "--json"]
    doc = json.loads(_run([*args, "--seed", "3"]).output)
    again = json.loads(_run([*args, "--seed", "3"]).output)
    other = json.loads(_run([*args, "--seed", "4"]).output)
    exact = json.loads(_run(["simulate", "--table", "shifted", "--turn-cycle", tc,
                             "--json"]).output)
    assert doc == again and doc["walked"] != other["walked"]
    assert doc["poses"] == exact["poses"]  # the printed path stays the noise-free one
    w = doc["walked"]
    assert w["walks"] == 400 and w["seed"] == 3 and w["step_noise"]["dH"] == 1.0
    fit, _ = walk_many(shifted_table().rows, parse_turn_cycle(tc), 400, 200, (),
                       parse_step_noise("0.3,1"), np.random.default_rng(3))
    f = fit.fitness
    assert w["fitness"] == {"mean": round(float(f.mean()), 2), "median": float(np.median(f)),
                            "p10": float(np.percentile(f, 10)),
                            "p90": float(np.percentile(f, 90))}
    assert w["fitness"]["p10"] < w["fitness"]["p90"]  # the noise spreads the fitness
    text = _run(args[:-1] + ["--seed", "3"]).output
    assert "400 walks with step noise 0.3 cm F" in text and "90th percentile" in text


def test_simulate_walks_compose_with_the_placement_error():
    args = ["simulate", "--table", "shifted", "--turn-cycle", TC, "--step-noise", "0.3,1",
            "--walks", "100", "--json"]
    plain = json.loads(_run(args).output)["walked"]
    placed = json.loads(_run([*args, "--placement-error", "0.5,1"]).output)["walked"]
    assert placed["placement"] == "0.5,1" and plain["placement"] is None
    assert placed["fitness"] != plain["fitness"] or placed["blocks_covered"] != \
        plain["blocks_covered"]


def test_simulate_plots_the_spread_of_the_walks(tmp_path, monkeypatch):
    from pac_host import plots

    seen = {}
    real = plots._save

    def save(fig, path):
        seen[path.name] = (len(fig.axes[0].lines), fig.axes[0].get_title().replace("\n", " "))
        return real(fig, path)

    monkeypatch.setattr(plots, "_save", save)
    _run(["simulate", "--turn-cycle", TC, "--plot", str(tmp_path / "a.png")])
    _run(["simulate", "--turn-cycle", TC, "--plot", str(tmp_path / "b.png"),
          "--step-noise", "0.3,1", "--walks", "100"])
    assert seen["b.png"][0] >= seen["a.png"][0] + 40  # 40 of the walks, thin (and more rows)
    assert "40 of 100 walks with step noise 0.3,1" in seen["b.png"][1]
    assert (tmp_path / "b.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, words", [
    (["--step-noise", "-0.3,1"], "must be >= 0"),
    (["--step-noise", "0.3,-1"], "must be >= 0"),
    (["--step-noise", "20,1"], "at most 10 cm"),
    (["--step-noise", "0.3,90"], "30 deg"),
    (["--step-noise", "0.3"], "takes CM,DEG"),
    (["--step-noise", "a,b"], "takes CM,DEG"),
    (["--step-noise", "nan,1"], "finite"),
    (["--step-noise", "0.3,1", "--walks", "0"], "--walks must be 1..100000"),
    (["--step-noise", "0.3,1", "--walks", "100001"], "--walks must be 1..100000"),
    (["--walks", "10"], "give --step-noise or --placement-error"),
    (["--step-noise", "none", "--walks", "10"], "give --step-noise or --placement-error"),
])
def test_simulate_bad_step_noise_or_walks_is_one_line(args, words):
    res = CliRunner().invoke(main, ["simulate", "--turn-cycle", TC, *args])
    assert res.exit_code == 2, res.output
    assert words in res.output and "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_step_noise_values_refused_by_the_definition():
    with pytest.raises(InputError):
        parse_step_noise("inf,1")
