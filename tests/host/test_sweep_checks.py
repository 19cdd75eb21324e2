"""A sweep file is checked whole before any cell runs: every value in its range, one line naming
the setting and the range (exit 2); a local Dask cluster that cannot start is one line saying
what runs without it (exit 1)."""

from __future__ import annotations

import typing

import pytest
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.experiments.sweep import settings
from pac_host.experiments.sweep.settings import RANGES, setting_names

from .test_faults_disk import one_line


def _sweep(tmp_path, body: str, *args: str):
    path = tmp_path / "sweep.toml"
    path.write_text(body + '\n[[cells]]\nmethods = "oracle"\n')
    return CliRunner().invoke(main, ["sweep", str(path), "--out", str(tmp_path / "out"), *args])


@pytest.mark.parametrize("setting, words", [
    ("[settings]\nperturb_prob = 1.5", "setting 'perturb_prob' must be in [0, 1] (a probability), "
                                       "got 1.5"),
    ("[grid]\nperturb_prob = [0.25, -0.5]", "setting 'perturb_prob' must be in [0, 1]"),
    ("[settings]\npal.cga.bit_mutation_rate = nan",
     "setting 'bit_mutation_rate' must be in [0, 1]"),
    ("[settings]\nseeds = 0", "setting 'seeds' must be 1..10000, got 0"),
    ("[settings]\ninterval = -40", "setting 'interval' must be 1..100000"),
    ("[settings]\nperturb_reps = 64", "setting 'perturb_reps' must be 0..63"),
    ("[settings]\nexplore = 1.0", "setting 'explore' must be in [0, 1)"),
    ("[settings]\nscale = [1.0, -1.0, 2.0]", "setting 'scale' must be in [0, inf)"),
    ("[settings]\npal.model.elite = 8\nmodel_population = 8",
     "setting 'pal.model.elite' must be at most 7 with model_population 8, got 8"),
])
def test_a_value_out_of_its_range_is_one_line_before_any_cell_runs(tmp_path, setting, words):
    one_line(_sweep(tmp_path, setting), 2, words)
    assert not (tmp_path / "out").exists()


def test_every_numeric_setting_has_a_range():
    """A number added to the configuration is range-checked in a sweep file too."""
    def numeric(hint) -> bool:
        args = typing.get_args(hint) or (hint,)
        return any(a in (int, float) or numeric_tuple(a) for a in args)

    def numeric_tuple(hint) -> bool:
        return typing.get_origin(hint) is tuple and all(
            a in (int, float, Ellipsis) for a in typing.get_args(hint))

    types = settings._field_types()
    missing = [".".join(p) for p in set(setting_names().values())
               if numeric(types[p]) and p not in RANGES]
    assert not missing, f"no range for {missing} (pac_host/experiments/sweep/settings.py RANGES)"


def test_a_local_cluster_that_cannot_start_is_one_line(tmp_path, monkeypatch):
    import distributed

    def nanny_fails(*args, **kw):
        raise RuntimeError("Nanny failed to start.\nmore detail")

    monkeypatch.setattr(distributed, "LocalCluster", nanny_fails)
    one_line(_sweep(tmp_path, "[settings]\nseeds = 1", "--jobs", "2"), 1,
             "the local Dask cluster of 2 workers could not start (Nanny failed to start.)",
             "--jobs 1 runs the work in this process, without Dask")
