"""`pac-host evolve`: PAL with the robot link (the built-in emulator without --port)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from pac_host import limits
from pac_host.cli.link_options import ask, confirm, emulator_options, given, link_options
from pac_host.cli.options import (
    Bounded,
    explore_option,
    kick_length_cost_option,
    learning_options,
    placement_option,
    profile_option,
    profile_pal,
    search_chains_option,
    search_evaluations_option,
    search_models_option,
    shapes_option,
    shorten_after_option,
)
from pac_host.cli.progress import Progress, quiet_option
from pac_host.cli.resume import jsonable, refuse, saved_doc, took_line
from pac_host.coverage.placement import HAND, parse_placement
from pac_host.errors import InputError
from pac_host.model.table import BUILTIN
from pac_host.robot.connect import check_connection, connect
from pac_host.robot.evolve import (
    CONFIG_FORMAT,
    EvolveConfig,
    check_new_run,
    evolve,
    load_config,
    recovery_summary,
    save_config,
)
from pac_host.robot.observers import ManualObserver
from pac_host.robot.recovery import describe_counts


@click.command("evolve")
@link_options
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Directory for the run's files (required unless --resume).")
@click.option("--resume", "resume_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Continue the run in this directory from its last complete punctuation, "
                   "with the options it was started with (an option typed that differs is "
                   "refused; --generations may carry a run on).")
@click.option("--generations", default=1000, show_default=True, type=Bounded(limits.GENERATIONS),
              help="CGA generations in all.")
@click.option("--interval", default=40, show_default=True, type=Bounded(limits.INTERVAL),
              help="CGA generations between punctuations (tests on the robot).")
@click.option("--method", default="partial", show_default=True,
              type=click.Choice(["partial", "full"]),
              help="The model GA's recombination (the paper's partial, or full); refused where "
                   "no model GA runs (the default profile, unless --model-generations N).")
@click.option("--model-fitness", default="coverage", show_default=True,
              type=click.Choice(["coverage", "steps"]),
              help="Model GA score: the paper's six coverage differences, or the observed "
                   "paths' one-step residuals (needs a tracker, not manual counts).")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED),
              help="Seeds the GAs and the emulator's per-run tracker noise.")
@click.option("--budget", default=200, show_default=True, type=Bounded(limits.BUDGET),
              help="Gait cycles per test run.")
@click.option("--model", "model_spec", default="measured", show_default=True,
              metavar="measured|shifted|FILE", help="The model the CGA starts on.")
@click.option("--cga-population", default=128, show_default=True,
              type=Bounded(limits.CGA_POPULATION))
@click.option("--model-population", default=64, show_default=True,
              type=Bounded(limits.MODEL_POPULATION))
@click.option("--model-generations", default=None, type=Bounded(limits.MODEL_GENERATIONS),
              help="Model GA generations per punctuation [default: 40 with --correction ga, "
                   "0 with fit: the fitted table alone]")
@click.option("--initial-generations", default=200, show_default=True,
              type=Bounded(limits.GENERATIONS),
              help="CGA generations on the model before the first test.")
@learning_options
@profile_option()
@search_evaluations_option()
@search_models_option()
@search_chains_option()
@explore_option()
@kick_length_cost_option()
@shorten_after_option()
@shapes_option()
@click.option("--search-while-walking/--no-search-while-walking", default=None,
              help="Also search while the robot walks the tests, on the model they were chosen "
                   "on (its 13 minutes become search time; the run is then not reproducible "
                   "from its seed). [default: on with --port, off with the built-in emulator]")
@placement_option(None, f"{HAND.to_text()} with an anytime profile, none with paper")
@quiet_option
def evolve_cmd(out_dir, resume_dir, generations, interval, method, model_fitness, seed, budget,
               model_spec, cga_population, model_population, model_generations, initial_generations,
               correction, structure, tests, operational, placement, profile, search_evaluations,
               search_models, search_chains, explore, kick_length_cost, shorten_after, shapes,
               search_while_walking, port, observer_spec, placer, quiet,
               **sim) -> None:
    """Co-evolve the model and the turn cycle with tests on the robot (PAL).

    Every INTERVAL CGA generations the best turn cycle and two perturbations of it run on the
    robot from the start pose (45, 30, 90) for BUDGET gait cycles each; an observer reports the
    path; the model is corrected (by default fitted to every observed step; with --profile
    paper by the paper's model GA with partial recombination, or full with --method full);
    the robot's operational turn cycle is replaced only when a new one does better on the
    robot. A person places a real robot at each start pose when asked (press Enter); the
    built-in emulator is placed through its tracker.

    With the default profile each punctuation's tests correct the model and the turn-cycle
    search then spends a budget of evaluations on it (the same run on any machine); on a real
    robot (--port) it also searches while the robot walks the tests (--no-search-while-walking
    keeps a run reproducible); --profile paper runs INTERVAL generations of the paper's CGA
    between punctuations instead.

    Progress goes to stderr (a line per punctuation through a pipe; on a real robot also the
    tests and gait cycles walked, at most every half minute); --quiet silences it.

    Writes OUT/log.jsonl (a line per punctuation), observations.jsonl (every observation, as
    it happens), runs.jsonl (observed runs, for `pac-host diagnose`), model.json,
    turn_cycle.json, coverage_path.png, learning_progress.png and state.json.

    Examples: pac-host evolve --out out/evolve --generations 200;
    pac-host evolve --port /dev/ttyUSB0 --observer tracker:192.168.1.5:7000 --out out/robot
    """
    if resume_dir is not None:
        if out_dir is not None and Path(out_dir) != Path(resume_dir):
            raise InputError("give either --out or --resume DIR (the run's own directory)")
        saved_doc(resume_dir, "config.json", CONFIG_FORMAT, "an evolve run")
        root, cfg = resume_dir, load_config(resume_dir)
        _check_resume(cfg, port)
        if given("generations"):  # a finished run may be carried on further
            cfg = replace(cfg, generations=generations)
        if port is None:  # the same emulated world as before, unless told otherwise
            for name, value in cfg.robot.get("emulator", {}).items():
                if not given(name):
                    sim[name] = tuple(value) if isinstance(value, list) else value
    elif out_dir is None:
        raise InputError("--out DIR is required (or --resume DIR)")
    else:
        root = out_dir
        check_new_run(root)
        learn = profile_pal(profile, search_evaluations, model_generations,
                            dict(model_fitness=model_fitness, correction=correction,
                                 structure=structure, tests=tests, operational=operational,
                                 placement=placement, search_models=search_models,
                                 search_chains=search_chains, explore=explore,
                                 kick_length_cost=kick_length_cost, shorten_after=shorten_after,
                                 shapes=shapes), paths_observed=observer_spec != "manual")
        from pac_host.learning.config import NO_MODEL_GA, RUN_THE_GA, recombination_inert

        if given("method") and observer_spec != "manual" and recombination_inert(learn):
            # (counts from a person need the paper's model GA: there --method matters)
            raise InputError(f"--method chooses the model GA's recombination, and the "
                             f"{profile} profile {NO_MODEL_GA}; {RUN_THE_GA}")
        if placement is None:  # a robot is placed by hand (or seen through a noisy tracker)
            learn = replace(learn, placement="none" if learn.search == "cga" else HAND.to_text())
        if search_while_walking is None:
            search_while_walking = port is not None and learn.search != "cga"
        if search_while_walking and learn.search == "cga":
            raise InputError(f"--search-while-walking needs an anytime profile, not "
                             f"--profile {profile}")
        cfg = EvolveConfig(seed=seed, method=method, model_fitness=learn.model_fitness,
                           search=learn.search, search_evaluations=learn.search_evaluations,
                           search_while_walking=search_while_walking,
                           generations=generations, interval=interval,
                           model_generations=model_generations, cga_population=cga_population,
                           model_population=model_population, budget=budget,
                           initial_generations=initial_generations,
                           model=_spec(model_spec), robot=_robot(port, observer_spec, sim),
                           correction=learn.correction, structure=learn.structure,
                           tests=learn.tests, operational=learn.operational,
                           placement=learn.placement, search_models=learn.search_models,
                           search_chains=learn.search_chains,
                           explore=learn.explore,
                           kick_length_cost=learn.kick_length_cost,
                           shorten_after=learn.shorten_after,
                           shorten_windows=learn.shorten_windows,
                           library_restarts=learn.library_restarts,
                           finish_moves=learn.finish_moves,
                           refine_effects=learn.refine_effects,
                           operational_evidence=learn.operational_evidence,
                           search_noise=learn.search_noise,
                           noisy_search_scale=learn.noisy_search_scale,
                           shapes=learn.shapes)
    # every value in range and every input file read (the model, the library of sweeps; the
    # emulator's table and effects below) before a port is opened or a file is written
    cfg.check()
    emu = emulator_options(sim, port)
    check_connection(port, observer_spec, emu, placer)
    if resume_dir is not None and given("generations"):
        save_config(root, cfg)
    with connect(port, observer_spec, emu, ask, confirm, placer=placer) as conn:
        click.echo(f"robot: {conn.description}; observer: {conn.observer.name}")
        if resume_dir is None and isinstance(conn.observer, ManualObserver) and cfg.needs_paths():
            cfg = cfg.for_counts_only()
            click.echo("the observer reports coverage counts only, not paths: using the "
                       "paper's model GA with its six coverage differences "
                       "(--correction ga --model-fitness coverage)")

        from pac_host.learning.model_ga import ERROR_UNITS

        def show(rec: dict) -> None:
            figs = "/".join(str(o["fitness"]) for o in rec["observed"])
            click.echo(f"generation {rec['generation']}: tests {figs} on the robot (fitness); "
                       f"model error {rec['model_error_before']} -> {rec['model_error_after']} "
                       f"{ERROR_UNITS[rec['model_fitness']]}; "
                       f"operational {rec['operational']} {operational_figure(rec)}")

        with Progress("evolve", quiet, minor=("tests", "gait cycles"),
                      minor_every=30.0) as progress:
            last = evolve(root, cfg, conn, resume=resume_dir is not None, on_punctuation=show,
                          progress=progress)
    if last:
        click.echo(f"operational turn cycle {last['operational']} ("
                   f"{operational_figure(last)} on the robot); files in {root}")
        rec = recovery_summary(root)
        if rec:
            click.echo(describe_counts(rec))


def operational_figure(rec: dict) -> str:
    """The operational turn cycle's figure of a punctuation record: its walk's fitness, and
    where step noise is estimated above zero, that it is one walk and the expectation with
    its interval and the walks behind it.

    >>> operational_figure({"operational_fitness": 45})
    'fitness 45'
    >>> operational_figure({"operational_fitness": 45, "step_noise": {"clear": True},
    ...     "operational_estimate": {"mean": 22.4, "interval": [19.1, 25.7], "walks": 6}})
    'fitness 45 (one walk), expected 22.4 [19.1, 25.7] over 6 walks'
    """
    fit = f"fitness {rec['operational_fitness']}"
    est = rec.get("operational_estimate")
    if not (rec.get("step_noise") or {}).get("clear") or not est:
        return fit
    n = est["walks"]
    over = f"over {n} walk{'s' if n != 1 else ''}"
    if est.get("interval") is None:
        return f"{fit} (one walk), mean {est['mean']:g} {over}"
    lo, hi = est["interval"]
    return f"{fit} (one walk), expected {est['mean']:g} [{lo:g}, {hi:g}] {over}"


def _saved_options(cfg: EvolveConfig, port: str | None) -> dict[str, object]:
    """The options a saved run was started with, as a resume compares typed ones (the
    defaults a profile chose included; --generations is not one: a run may be carried on)."""
    from dataclasses import fields

    from pac_host.learning import profiles

    names = {p.name for p in click.get_current_context().command.params}
    out: dict[str, object] = {f.name: getattr(cfg, f.name) for f in fields(cfg)
                              if f.name in names and f.name != "generations"}
    out["model_spec"] = cfg.model
    out["profile"] = next((p for p, o in profiles.PROFILES.items()
                           if o.get("search") == cfg.search), None)
    if port is None and "emulator" in cfg.robot:
        out.update(cfg.robot["emulator"])
    return out


def _typed_value(name: str, value):
    """A typed option's value as the saved config holds it."""
    if name in ("model_spec", "sim_table"):
        return _spec(value)
    if name == "placement":
        p = parse_placement(value)
        return "none" if p is None else p.to_text()
    return jsonable(value)


def _check_resume(cfg: EvolveConfig, port: str | None) -> None:
    """--resume: options typed that differ from the saved run's are refused, each named; the
    saved values of those left out are taken (a line says which)."""
    params = click.get_current_context().params
    differ, taken = [], {}
    for name, was in _saved_options(cfg, port).items():
        now = _typed_value(name, params[name]) if params.get(name) is not None else None
        if given(name):
            if now != jsonable(was):
                differ.append((name, now, jsonable(was)))
        elif now != jsonable(was):
            taken[name] = jsonable(was)
    refuse(differ, "--out")
    click.echo(took_line(taken))


def _spec(table: str) -> str:
    """A table spec that still means the same file when resumed from elsewhere."""
    return table if table in BUILTIN else str(Path(table).resolve())


def _robot(port: str | None, observer: str | None, sim: dict) -> dict:
    if port is not None:
        return {"port": port, "observer": observer}
    step = {} if sim["sim_step_noise"] is None else {"sim_step_noise": sim["sim_step_noise"]}
    return {"emulator": {"sim_table": _spec(sim["sim_table"]),
                         "sim_effects": list(sim["sim_effects"]), "sim_noise": sim["sim_noise"],
                         **step}}


def register(main: click.Group) -> None:
    main.add_command(evolve_cmd)
