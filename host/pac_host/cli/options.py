"""Option types and helpers shared by the commands (parsing stays in the CLI layer)."""

from __future__ import annotations

import sys

import click

from pac_host import limits
from pac_host.errors import InputError, exit_code
from pac_host.limits import Bound
from pac_host.model import load_with_effects  # noqa: F401  (re-exported for the commands)
from pac_host.model.effects_module import load_effects_module
from pac_host.search.shorten import MAX_SHORTEN_AFTER


class Bounded(click.ParamType):
    """An integer option held to a :class:`~pac_host.limits.Bound`: outside it, one line naming
    the option, the range and why, and exit 2. The help shows the range as the metavar."""

    name = "integer"

    def __init__(self, bound: Bound) -> None:
        self.bound = bound

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return self.bound.describe()

    def convert(self, value, param, ctx) -> int:
        v = value if isinstance(value, int) else click.INT.convert(value, param, ctx)
        name = param.opts[0] if param is not None and param.opts else "value"
        return self.bound.check(v, name)


def table_option(default: str = "measured", help_text: str | None = None):
    return click.option(
        "--table",
        "table_spec",
        default=default,
        show_default=True,
        metavar="measured|shifted|FILE",
        help=help_text or "Gait table: a built-in name or a pac-gait-table/1 JSON file.",
    )


def effect_option():
    return click.option(
        "--effect",
        "effect_specs",
        multiple=True,
        metavar="NAME:P=V,...",
        help="Add an unmodelled effect, e.g. transition:alpha=0.3 (repeatable).",
    )


_SEARCH_HELP = ("Score each turn cycle from a stencil of start poses around the start, for a "
                "robot placed by hand with these standard deviations (none: the exact start).")


def placement_option(default: str | None = "none", shown: str | bool = True,
                     help: str = _SEARCH_HELP):
    """``--placement-error POS_CM,HEAD_DEG``: a robot placed by hand with these standard
    deviations (:mod:`pac_host.coverage.placement`); by default the searches' help (sweeps that keep
    their coverage so placed)."""
    return click.option(
        "--placement-error", "placement", default=default, show_default=shown,
        metavar="POS_CM,HEAD_DEG|none", help=help)


def step_noise_option(help: str, name: str = "--step-noise"):
    """``--step-noise CM,DEG``: each executed gait cycle's move varies by these standard
    deviations (cm on F and T, deg on dH; :mod:`pac_host.model.step_noise`); not given: the
    table file's (none for a built-in table)."""
    return click.option(name, name.lstrip("-").replace("-", "_"), default=None,
                        metavar="CM,DEG|none", help=help)


def placed_text(placed: dict, error) -> str:
    """How the commands print a turn cycle's fitness from drawn start poses
    (:func:`pac_host.coverage.placement.summary` of walks drawn with ``error``, a
    PlacementError)."""
    return (f"from {placed['walks']} start poses drawn at {error.pos_cm:g} cm, "
            f"{error.head_deg:g} deg: mean fitness {placed['mean']}, median "
            f"{placed['median']:g}, 10th percentile {placed['p10']:g}")


def _load_modules(ctx: click.Context, param: click.Parameter, value: tuple[str, ...]) -> None:
    try:
        for path in value:
            load_effects_module(path)
    except InputError as e:  # raised while parsing, before the command's own error handling
        click.echo(f"{ctx.find_root().info_name}: error: {e}", err=True)
        ctx.exit(exit_code(e))


def effects_module_option():
    """``--effects-module FILE`` (repeatable): user-defined effects, loaded before any other
    option is used, so tables and ``--effect`` may name them."""
    return click.option(
        "--effects-module",
        multiple=True,
        metavar="FILE.py",
        is_eager=True,
        expose_value=False,
        callback=_load_modules,
        help="Python file defining effects with pac_host.model.effects.register_effect "
             "(repeatable; see docs/reference/effects.md).",
    )


def progress_enabled() -> bool:
    """Progress bars go to stderr, and only when it is a terminal."""
    return sys.stderr.isatty()


def profile_option():
    from pac_host.learning import profiles

    return click.option(
        "--profile", default=profiles.DEFAULT, show_default=True,
        type=click.Choice(sorted(profiles.PROFILES)),
        help="paper: the paper's method, its model GA with partial (or full) recombination "
             "and 40 CGA generations between punctuations; default: the model fitted to every "
             "observed step (no model GA) and anytime PAL, a budget of search evaluations per "
             "punctuation.")


def search_evaluations_option():
    return click.option(
        "--search-evaluations", type=Bounded(limits.SEARCH_EVALUATIONS), default=None,
        help="Turn-cycle search evaluations per punctuation (default profile; "
             "overrides the profile's).")


def search_models_option():
    return click.option(
        "--search-models", type=Bounded(limits.SEARCH_MODELS), default=1, show_default=True,
        help="Score each turn cycle on this many tables, the corrected model and draws from "
             "its posterior, pooled: the search prefers turn cycles whose rows the tests have "
             "pinned (an anytime profile; each table costs an evaluation).")


def search_chains_option():
    return click.option(
        "--search-chains", type=Bounded(limits.CHAINS), default=None,
        help="Independent search chains on each corrected model, each with the whole budget "
             "and carried on between punctuations; the best any finds is tested (an anytime "
             "profile; host time for more basins, not a longer climb in one) "
             "[default: the profile's]")


def kick_length_cost_option(default: float | None = None):
    """``--kick-length-cost``; without a ``default``, the profile's (PAL's commands)."""
    return click.option(
        "--kick-length-cost", type=float, default=default, show_default=default is not None,
        metavar="CM",
        help="Weigh each gait cycle of a kicked loop as this many cm of the closing kick's "
             "repair error, so the kicks prefer shorter loops with the same net move (1 is "
             "the value measured; 0: closeness alone)" + (
                 "" if default is not None
                 else " (an anytime profile) [default: the profile's]"))


def shorten_after_option(default: int | None = None):
    """``--shorten-after``; without a ``default``, the profile's (PAL's commands)."""
    return click.option(
        "--shorten-after", type=click.IntRange(0, MAX_SHORTEN_AFTER), default=default,
        show_default=default is not None, metavar="KICKS",
        help="After this many kicks in a row without progress a search chain tries shorter "
             "loops of its sweep, two genes re-set so each pass ends where it did (0: never)" + (
                 "" if default is not None
                 else " (an anytime profile) [default: the profile's]"))


def explore_option():
    return click.option(
        "--explore", type=click.FloatRange(0.0, 1.0, max_open=True), default=None,
        metavar="SHARE",
        help="Spend this share of each punctuation's search budget on a draw from the "
             "corrected model's posterior, from the search's best, and test the best found "
             "there after the best (Thompson sampling: rows no test has pinned get tested when "
             "a plausible table favours them; an anytime profile) "
             "[default: the profile's]")


def shapes_option(default: str | None = None):
    return click.option(
        "--shapes", "shapes", default=default, show_default=default is not None,
        metavar="builtin|none|FILE",
        help="Sweeps known to be good (a pac-shapes/1 file, or the project's: builtin), "
             "re-expressed on each model the search starts on; none: start from short CGA "
             "runs alone." + ("" if default else " [default: builtin with an anytime "
                              "profile, none with paper]"))


def profile_pal(profile: str, search_evaluations: int | None, model_generations: int | None,
                options: dict, paths_observed: bool = True, **fields):
    """The PAL settings of a profile: ``fields`` under it, the profile's overrides, then those
    of ``options`` typed on the command line (the rest keep the profile's values), then the
    search budget and the model GA generations (by the correction unless given).

    A typed ``--model-fitness coverage`` where the model is fitted to every observed step is
    refused: the fit scores steps whatever it says (``paths_observed`` False: an observer of
    counts only, where the run falls back to the paper's model GA and the option matters)."""
    from dataclasses import replace

    from pac_host.learning import profiles
    from pac_host.learning.config import PALConfig, model_generations_for

    cfg = profiles.apply(profile, replace(PALConfig(), **fields))
    src = click.get_current_context().get_parameter_source
    typed = {k: v for k, v in options.items()
             if getattr(src(k), "name", "") in ("COMMANDLINE", "ENVIRONMENT")}
    cfg = replace(cfg, **typed)
    if (paths_observed and cfg.correction == "fit"
            and typed.get("model_fitness", "steps") != "steps"):
        raise InputError(f"--model-fitness {typed['model_fitness']} scores the model GA's "
                         "models on block counts, and with --correction fit (the "
                         f"{profile} profile's) the model is fitted to every observed step "
                         "and scored on the steps; use --profile paper or --correction ga")
    if search_evaluations is not None:
        if cfg.search == "cga":
            raise InputError("--search-evaluations needs an anytime profile, not "
                             f"--profile {profile}")
        cfg = replace(cfg, search_evaluations=search_evaluations)
    if model_generations is not None or "model_generations" not in profiles.PROFILES[profile]:
        cfg = replace(cfg, model_generations=model_generations_for(cfg.correction,
                                                                   model_generations))
    cfg.check()
    return cfg
def learning_options(f):
    """How PAL learns the robot: the model correction, the tests, the operational rule
    (defaults: :class:`pac_host.learning.pal.PALConfig`'s; ``--correction ga --tests paper
    --operational best --model-fitness coverage`` is the paper's method)."""
    from pac_host.learning import model_fit, pal, test_selection

    d = pal.PALConfig()
    opts = [
        click.option("--correction", default=d.correction, show_default=True,
                     type=click.Choice(pal.CORRECTIONS),
                     help="ga: the model GA alone (the paper); fit: the whole table fitted to "
                          "every observed step (effects of the library, then rows weighted by "
                          "their evidence), then --model-generations of the model GA on top."),
        click.option("--structure", default=d.structure, show_default=True,
                     type=click.Choice(model_fit.STRUCTURES),
                     help="With --correction fit: fit the effects library (effects) or only "
                          "the rows (none)."),
        click.option("--tests", default=d.tests, show_default=True,
                     type=click.Choice(test_selection.CHOICES),
                     help="paper: the best turn cycle and two perturbations; informative: the "
                          "best and the two candidates the models disagree on most; rows: as "
                          "informative, the candidates including the best with a pair swapped "
                          "for a row no test has pinned."),
        click.option("--operational", default=d.operational, show_default=True,
                     type=click.Choice(pal.OPERATIONAL),
                     help="best: only the CGA's best may replace the operational turn cycle "
                          "(the paper); tested: any tested turn cycle that did better."),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f
