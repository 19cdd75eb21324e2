"""`pac-host experiment`: the paper's PAL experiment, full against partial recombination."""

from __future__ import annotations

from pathlib import Path

import click

from pac_host import limits
from pac_host.cli.cluster_options import scheduler_options
from pac_host.cli.options import (
    Bounded,
    effect_option,
    effects_module_option,
    explore_option,
    kick_length_cost_option,
    learning_options,
    load_with_effects,
    placement_option,
    profile_option,
    profile_pal,
    search_chains_option,
    search_evaluations_option,
    search_models_option,
    shapes_option,
    shorten_after_option,
    step_noise_option,
)
from pac_host.cli.progress import Progress, quiet_option
from pac_host.cli.resume import options_doc, resumable
from pac_host.coverage import DEFAULT_BUDGET, check_budget
from pac_host.coverage.placement import HAND, WALKS
from pac_host.errors import FileFault, InputError, PacError, with_hint
from pac_host.experiments.executors import make_executor
from pac_host.experiments.experiment import (
    OPTIMUM_EVALUATIONS,
    OPTIMUM_EVALUATIONS_FLOOR,
    PAPER_GENERATIONS,
    ExperimentConfig,
    default_methods,
    optimum_evaluations_for,
    run_experiment,
)
from pac_host.learning import profiles
from pac_host.model import resolve_table
from pac_host.model.effects import BUILT_IN
from pac_host.model.table import BUILTIN

CONFIG_FORMAT = "pac-experiment-config/1"  # OUT/config.json, what --resume checks
# the options given to the PAL settings, whose defaults are the profile's
_PAL_OPTIONS = ("model_fitness", "correction", "structure", "tests", "operational", "placement",
                "search_models", "search_chains", "explore", "kick_length_cost",
                "shorten_after", "shapes", "search_evaluations", "model_generations")


@click.command("experiment")
@click.option("--seeds", default=5, show_default=True, type=Bounded(limits.SEEDS),
              help="Starting populations (the paper used 5).")
@click.option("--generations", default=1000, show_default=True, type=Bounded(limits.GENERATIONS),
              help="CGA generations per run; a punctuation every 40.")
@click.option("--methods", default=None,
              help="Comma-separated: full, partial, and the control oracle (the CGA on the "
                   "actual robot's own table: the ceiling). Full and partial differ only in "
                   "the model GA's recombination: under a profile that runs no model GA (the "
                   "default, unless --model-generations N) full is refused. [default: "
                   "full,partial,oracle with --profile paper; partial,oracle with the default]")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory for summary.json, log.jsonl, optimum.json and the PNG plots.")
@click.option("--jobs", default=1, show_default=True, type=click.IntRange(1, 64),
              help="Worker processes; results do not depend on it.")
@click.option("--seed", "base_seed", default=0, show_default=True,
              type=Bounded(limits.SEED),
              help="Base seed: the whole experiment is a function of it.")
@click.option("--actual", "actual_spec", default="shifted", show_default=True,
              metavar="measured|shifted|FILE",
              help="The simulated actual robot: a built-in table or a pac-gait-table/1 file "
                   "(its effects included).")
@effect_option()
@step_noise_option("The actual robot's step noise: each executed gait cycle's move varies "
                   "by these standard deviations, cm on F and T, deg on dH, drawn from the "
                   "run's seed (not given: the --actual file's, if any; none: no noise); the "
                   "model the learner starts from stays noise-free.")
@effects_module_option()
@click.option("--model", "model_spec", default="measured", show_default=True,
              metavar="measured|shifted|FILE", help="The model the CGA starts on.")
@click.option("--model-fitness", default="coverage", show_default=True,
              type=click.Choice(["coverage", "steps"]),
              help="Model GA score: the paper's six coverage differences, or one-step "
                   "residuals of the observed paths (a project extension).")
@click.option("--budget", default=DEFAULT_BUDGET, show_default=True, type=Bounded(limits.BUDGET),
              help="Gait cycles per test run.")
@click.option("--initial-generations", default=1000, show_default=True,
              type=Bounded(limits.GENERATIONS),
              help="Length of the CGA run on the model that seeds each population.")
@click.option("--optimum-runs", default=8, show_default=True, type=Bounded(limits.RUNS),
              help="Long searches on the actual table that establish the optimum (raised to "
                   "the best any run shows on the robot).")
@click.option("--optimum-generations", default=3000, show_default=True,
              type=Bounded(limits.GENERATIONS), help="Length of each optimum run (paper profile).")
@click.option("--optimum-evaluations", default=None, type=Bounded(limits.EVALUATIONS),
              help="Evaluations of each optimum run (`optimize` chains; default profile) "
                   f"[default: {OPTIMUM_EVALUATIONS:,} for {PAPER_GENERATIONS} --generations, "
                   f"in proportion to --generations, at least {OPTIMUM_EVALUATIONS_FLOOR:,}]")
@click.option("--best-known", type=int, default=None,
              help="The best coverage fitness known on the actual robot (verified with "
                   "`pac-host simulate`); punctuations to the target count against the highest "
                   "of it, the experiment's own optimum and, on a built-in robot at budget 200, "
                   "the project's record (pac_host/model/best_known.json).")
@click.option("--model-generations", default=None, type=Bounded(limits.MODEL_GENERATIONS),
              help="Model GA generations per punctuation [default: 40 with --correction ga, "
                   "0 with fit: the fitted table alone]")
@learning_options
@profile_option()
@search_evaluations_option()
@search_models_option()
@search_chains_option()
@explore_option()
@kick_length_cost_option()
@shorten_after_option()
@shapes_option()
@click.option("--resume", is_flag=True,
              help="Continue an interrupted experiment in --out with the options it was "
                   "started with (OUT/config.json); an option typed that differs is refused.")
@scheduler_options
@placement_option()
@quiet_option
@resumable("out_dir", "config.json", CONFIG_FORMAT, "an experiment run",
           normalise=lambda n, v: _normalise(n, v))
def experiment_cmd(seeds, generations, methods, out_dir, jobs, base_seed, actual_spec,
                   effect_specs, step_noise, model_spec, model_fitness, budget, initial_generations,
                   optimum_runs, optimum_generations, optimum_evaluations, best_known,
                   model_generations, correction, structure, tests, operational, placement, profile,
                   search_evaluations, search_models, search_chains, explore, kick_length_cost,
                   shorten_after, shapes, resume, scheduler, connect_timeout, quiet) -> None:
    """Run PAL from N starting populations with each method.

    Under --profile paper the methods are the paper's: the model GA with full against partial
    recombination. The default profile fits the model to every observed step and runs no model
    GA, so recombination has nothing to act on: it runs partial (PAL as it is) alone.

    Each seed's starting population also runs the control "oracle": the same CGA on the actual
    robot's own table, the ceiling for a co-evolved model.

    --profile paper runs the paper's settings (40 CGA generations between punctuations; the
    optimum from long CGA runs); the default profile searches turn cycles with a budget of
    evaluations per punctuation (anytime PAL) and takes the optimum from `optimize` chains.

    Writes OUT/summary.json (per method and seed: operational coverage on the actual robot at
    each punctuation, the generation the optimum was first reached, the final model error per
    gait cycle; the comparison with exact tests over seeds, between the methods and against the
    oracle; robot time against the best known: the higher of the experiment's optimum, the
    record of a built-in actual robot and --best-known, which one in best_known),
    OUT/log.jsonl (one line per punctuation, appended as it happens), OUT/optimum.json (the
    experiment's own optimum on the actual robot) and PNG plots. Progress goes to stderr
    (through a pipe a line at each stage's start and per finished run); --quiet silences it.

    Example: pac-host experiment --profile paper --seeds 30 --generations 1000 --jobs 2
    --out out/paper
    """
    learn = profile_pal(profile, search_evaluations, model_generations,
                        dict(model_fitness=model_fitness, correction=correction,
                             structure=structure, tests=tests, operational=operational,
                             placement=placement, search_models=search_models,
                             search_chains=search_chains, explore=explore,
                             kick_length_cost=kick_length_cost, shorten_after=shorten_after,
                             shapes=shapes),
                        budget=check_budget(budget))
    cfg = ExperimentConfig(
        seeds=seeds, generations=generations,
        methods=(default_methods(learn) if methods is None
                 else tuple(m.strip() for m in methods.split(",") if m.strip())),
        base_seed=base_seed, initial_generations=initial_generations,
        optimum_runs=optimum_runs, optimum_generations=optimum_generations,
        optimum_search=profiles.OPTIMUM_SEARCH[profile],
        optimum_evaluations=_optimum_evaluations(optimum_evaluations, generations, profile),
        best_known=best_known,
        pal=learn,
    )
    cfg.check()  # before tables and workers: e.g. full where no model GA runs
    actual = load_with_effects(actual_spec, effect_specs, step_noise)
    model = resolve_table(model_spec)
    user = [e.name for e in (*actual.effects, *model.effects) if e.name not in BUILT_IN]
    if scheduler and user:  # a cluster's workers import the project, not the user's file
        raise InputError(f"effect {user[0]}: user-defined effects run with --jobs on this "
                         "machine, not on a --scheduler cluster")
    again = f"`pac-host experiment --out {out_dir} --resume` continues it"
    try:
        with Progress("experiment", quiet, UNITS) as progress, \
                make_executor(jobs, scheduler, connect_timeout) as engine:
            summary = run_experiment(out_dir, cfg, model, actual, engine, resume, progress,
                                     options=_saved_options(cfg))
    except FileFault as e:  # a full disk: the runs logged whole are kept
        if not (Path(out_dir) / "config.json").exists():
            raise
        raise with_hint(e, f"{again} (the runs logged whole are kept)") from None
    from pac_host.plots import experiment_plots  # matplotlib: not for `experiment --help`

    try:
        plots = experiment_plots(summary, out_dir)
    except PacError as e:  # the results are whole: only the plots are missing
        raise with_hint(e, f"the results are in {Path(out_dir) / 'summary.json'}; {again} "
                           "and draws the plots again") from None
    comp = summary["comparison"]
    click.echo(f"optimum on the actual robot ({actual.name}): fitness {summary['optimum']}")
    # on a noisy actual robot every coverage figure below is an expectation (one walk is luck)
    each = "" if summary["figures"] == "one walk" else f" ({summary['figures']})"
    if each:
        click.echo(f"operational coverage figures: {summary['figures']} of the actual robot "
                   "(log.jsonl: operational_expected, with its interval)")
    for m, s in comp["methods"].items():
        gen = s["mean_generation_reached"]
        vs = (f"; as good as the oracle on {s['matched_oracle']}/{s['seeds']} seeds (final "
              f"coverage against it, Wilcoxon p = "
              f"{s['final_coverage_vs_oracle_wilcoxon']['p_value']:.4g})"
              if "matched_oracle" in s else "")
        click.echo(f"{m:>8}: {s['reached_optimum']}/{s['seeds']} seeds reached the optimum"
                   f"{f' (mean generation {gen:.0f})' if gen is not None else ''}; "
                   f"mean final coverage {s['mean_final_coverage']:.2f}{each}{vs}")
    if "tests" in comp:
        t = comp["tests"]
        click.echo(f"reached optimum, Fisher exact p = {t['reached_optimum_fisher_exact_p']:.4g}; "
                   f"final coverage, Wilcoxon p = {t['final_coverage_wilcoxon']['p_value']:.4g}; "
                   f"mean coverage, Wilcoxon p = {t['mean_coverage_wilcoxon']['p_value']:.4g}")
    rt = summary["robot_time"]
    click.echo(f"best known {rt['best_known']} ({summary['best_known']['source']}); target "
               f"{rt['target']:.0%} of it{each}")
    for m, s in rt["methods"].items():
        med = s["median_punctuations_to_target"]
        click.echo(f"{m:>8}: reached the target on {s['reached_target']}/{s['seeds']} seeds, "
                   + (f"median {med} punctuations" if med is not None
                      else "median punctuations: not reached")
                   + (f" ({s['median_robot_hours_to_target']:.1f} robot hours)"
                      if s["median_robot_hours_to_target"] is not None else "")
                   + f"; ended at {rt['final_target']:.0%} on {s['ended_at_final_target']}/"
                   f"{s['seeds']}; {s['robot_hours_per_run']:.1f} robot hours per run")
        if s.get("mean_placed_fitness") is not None:
            click.echo(f"{'':>8}  final turn cycles placed by hand ({HAND.pos_cm:g} cm, "
                       f"{HAND.head_deg:g} deg; {WALKS} drawn start poses each): mean fitness "
                       f"{s['mean_placed_fitness']}")
    click.echo(f"summary: {out_dir / 'summary.json'}")
    click.echo("plots: " + ", ".join(str(p) for p in plots))


def _optimum_evaluations(given: int | None, generations: int, profile: str) -> int:
    """--optimum-evaluations as given, else in proportion to the run (the paper profile's
    optimum comes from CGA runs: its figure, unused, stays the paper's)."""
    if given is not None:
        return given
    if profiles.OPTIMUM_SEARCH[profile] != "optimize":
        return OPTIMUM_EVALUATIONS
    return optimum_evaluations_for(generations)


UNITS = {"optimum": "runs", "initial populations": "seeds", "pal": "runs"}


def _normalise(name: str, value):
    """An option's value as a run saves it and a resume compares it: a table or shapes file
    by its absolute path (the same file when resumed from elsewhere), the methods as a
    comma-separated list without spaces."""
    if name in ("actual_spec", "model_spec", "shapes") and value is not None \
            and value not in (*BUILTIN, "builtin", "none"):
        return str(Path(value).resolve())
    if name == "methods" and value is not None:
        return ",".join(m.strip() for m in value.split(",") if m.strip())
    return value


def _saved_options(cfg) -> dict:
    """OUT/config.json: the options, and the values the run took for those whose default
    the profile or other options choose (what a resume compares typed options against)."""
    pal = {n: getattr(cfg.pal, n) for n in _PAL_OPTIONS}
    return options_doc(CONFIG_FORMAT, normalise=_normalise, effective={
        **pal, "methods": ",".join(cfg.methods),
        "optimum_evaluations": cfg.optimum_evaluations})


def register(main: click.Group) -> None:
    main.add_command(experiment_cmd)
