"""A library of sweeps known to be good, and the search's starts made from them on a new model.

A search on a new model (another robot, or the model a punctuation's tests have just corrected)
need not start from nothing: the sweeps found on other tables, re-expressed on this one
(:mod:`pac_host.search.retarget`), are starting points a climb takes much further than from a
short CGA run. The library is a ``pac-shapes/1`` file: each sweep's turn cycle, the table it
was found on (a built-in table or robot name, or a ``pac-gait-table/1`` file beside the library)
and its fitness there. ``builtin`` is the project's (``shapes.json``): the best turn cycles
known on the built-in tables and robots, and the robust records of
:mod:`pac_host.model.best_known` (the best mean fitness known on each robot with step noise). A
sweep found for a noisy robot (its ``step_noise`` given) is a start only for a noisy search
(:meth:`Library.sources`): a noise-free search starts from the sharp sweeps alone, as before
there were robust ones. A chain also carries its own best from the model it had before
(:func:`carried`).

>>> lib = load("builtin")
>>> len(lib.without("shifted").shapes) < len(lib.shapes)
True
>>> from pac_host.model import shifted_table
>>> from pac_host.search.local import Objective
>>> objective = Objective(shifted_table().rows)
>>> x, score = starts(objective, lib.without("shifted").sources())[0]
>>> objective.fitness(score) >= 40, objective.evaluations < 10_000
(True, True)
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pac_host.coverage import format_turn_cycle, parse_turn_cycle
from pac_host.errors import InputError
from pac_host.files import write_atomic
from pac_host.model import best_known
from pac_host.model.effects import Effect
from pac_host.model.step_noise import parse_step_noise
from pac_host.model.table import BUILTIN, GaitTable, load_table
from pac_host.search.kicks import loop_table
from pac_host.search.neighbours import canonical
from pac_host.search.recent import Recent
from pac_host.search.retarget import BEAM, LENGTH_COST, retarget

FORMAT = "pac-shapes/1"
CHOICES = ("builtin", "none")  # or a file
_BUILTIN_FILE = Path(__file__).with_name("shapes.json")

# A source of starts: a turn cycle (9, 2) and the moves of the table it walks well on.
Source = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Shape:
    """One sweep of a library: its genes, the table it was found on, its fitness there."""

    genes: np.ndarray
    table: str
    fitness: int | None
    found_on: str
    step_noise: str | None = None  # the step noise it was found for (``CM,DEG``); None: none


@dataclass(frozen=True)
class Library:
    shapes: tuple[Shape, ...]
    folder: Path | None = None  # where table files named by the shapes are

    def without(self, robot: str) -> Library:
        """The library less the sweeps found on ``robot`` (to measure a method on a robot as
        on one nobody has searched)."""
        return Library(tuple(s for s in self.shapes if s.found_on != robot), self.folder)

    def sharp(self) -> Library:
        """The library less the sweeps found for a noisy robot: a noise-free search's starts."""
        return Library(tuple(s for s in self.shapes if s.step_noise is None), self.folder)

    def sources(self, noisy: bool = False) -> list[Source]:
        """Each sweep with its table's moves (:func:`pac_host.search.kicks.loop_table`): for a
        ``noisy`` search every sweep, else only the :meth:`sharp` ones."""
        return [(s.genes, _moves(s.table, self.folder))
                for s in (self if noisy else self.sharp()).shapes]

    def save(self, path: str | Path) -> Path:
        """Write the library as a ``pac-shapes/1`` file (whole or not at all); its path. Table
        files the shapes name are named from the new file's folder, so it loads anywhere."""
        folder = Path(path).resolve().parent
        write_atomic(path, json.dumps(self.to_json(lambda name: self._table_from(name,
                                                                                   folder))))
        return Path(path)

    def _table_from(self, name: str, folder: Path) -> str:
        """A shape's table as named from ``folder``: a built-in name as it is, a file by its
        path relative to ``folder`` (absolute where there is none, e.g. another drive)."""
        from pac_host.model import robots

        if name in BUILTIN or name in robots.ROBOTS:
            return name
        src = (Path(name) if self.folder is None else self.folder / name).resolve()
        try:
            return os.path.relpath(src, folder)
        except ValueError:
            return str(src)

    def to_json(self, table_name=lambda name: name) -> dict:
        return {"format": FORMAT, "shapes": [
            {"turn_cycle": format_turn_cycle(s.genes), "table": table_name(s.table),
             "fitness": s.fitness,
             "found_on": s.found_on,
             **({} if s.step_noise is None else {"step_noise": s.step_noise})}
            for s in self.shapes]}


def table_of(name: str, folder: Path | None = None) -> GaitTable:
    """A shape's table: a built-in table or robot name, or a table file (beside the library)."""
    from pac_host.model import robots

    if name in BUILTIN:
        return BUILTIN[name]()
    if name in robots.ROBOTS:
        return robots.build(name)
    path = Path(name) if folder is None else folder / name
    return load_table(path)


@functools.lru_cache(maxsize=64)
def _moves(name: str, folder: Path | None) -> np.ndarray:
    t = table_of(name, folder)
    return loop_table(t.rows, t.effects)


@functools.lru_cache(maxsize=8)
def load(spec: str) -> Library:
    """``builtin``, ``none`` or a ``pac-shapes/1`` file; bad input is an :class:`InputError`."""
    if spec == "none":
        return Library(())
    path = _BUILTIN_FILE if spec == "builtin" else Path(spec)
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read shapes file {spec}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"shapes file {spec} is not JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{spec} is not a {FORMAT} file")
    shapes = []
    folder = path.resolve().parent
    for k, item in enumerate(doc.get("shapes") or []):
        try:
            genes = parse_turn_cycle(str(item["turn_cycle"]))
            table = str(item["table"])
            fitness = None if item.get("fitness") is None else int(item["fitness"])
            found_on = str(item.get("found_on", table))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{spec}: shape {k} needs turn_cycle and table ({exc})") from None
        except InputError as exc:
            raise InputError(f"{spec}: shape {k}: {exc}") from None
        step_noise = item.get("step_noise")
        try:
            _moves(table, folder)
            if step_noise is not None and parse_step_noise(str(step_noise)).is_zero():
                step_noise = None
        except InputError as exc:
            raise InputError(f"{spec}: shape {k}: {exc}") from None
        shapes.append(Shape(genes, table, fitness, found_on,
                            None if step_noise is None else str(step_noise)))
    if spec == "builtin":
        shapes += _robust_records()
    return Library(tuple(shapes), folder)


def _robust_records() -> list[Shape]:
    """The robust best knowns (:func:`pac_host.model.best_known.entries`) as sweeps found
    for noisy robots, each on the robot it was found on."""
    return [Shape(parse_turn_cycle(rb["turn_cycle"]), name, None, name, rb["step_noise"])
            for name, rec in best_known.entries().items() for rb in rec.get("robust", [])]


def carried(genes: np.ndarray, rows: np.ndarray, effects: Sequence[Effect] = ()) -> Source:
    """A turn cycle found on a model (``rows``, ``effects``) as a source of starts on the next."""
    return np.asarray(genes), loop_table(rows, effects)


def proposals(sources: Sequence[Source], target: np.ndarray, budget: int,
              beam: int = BEAM, length_cost: float = LENGTH_COST) -> np.ndarray:
    """Every source re-expressed on the ``target`` table's moves, ``beam`` proposals each,
    canonical and without repeats (N, 9, 2). ``beam``, ``length_cost``: of the re-expression
    (:func:`pac_host.search.retarget.retarget`)."""
    return _proposals(sources, target, budget, beam, length_cost)[0]


# The last re-expressions, one a source, by what they depend on: a punctuation's search chains
# each re-express the library on the same corrected model, beside sources of their own, and the
# beam is most of what a chain's start costs (0.12 s a model for the library; the evaluations
# that score the proposals are still each chain's own)
_MEMO: Recent[np.ndarray] = Recent(64)  # a model's library and every chain's own sources


def _proposals(sources: Sequence[Source], target: np.ndarray, budget: int, beam: int = BEAM,
               length_cost: float = LENGTH_COST) -> tuple[np.ndarray, np.ndarray]:
    """:func:`proposals` and, for each, the index of the first source that proposed it."""
    if not sources:
        return np.zeros((0, 9, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    parts = [_retargeted(src, target, beam, length_cost) for src in sources]
    pop = canonical(np.concatenate(parts), budget)
    owner = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    _, first = np.unique(pop.reshape(len(pop), -1), axis=0, return_index=True)
    first = np.sort(first)
    return pop[first], owner[first]


def _retargeted(source: Source, target: np.ndarray, beam: int, length_cost: float
                ) -> np.ndarray:
    """One source re-expressed on ``target`` (:func:`pac_host.search.retarget.retarget`),
    remembered for the last few sources, targets and settings; the caller must not change it
    (:func:`_proposals` only reads it)."""
    key = (source_key(source), source_key((np.zeros(0), target)), int(beam), float(length_cost))
    genes, moves = source
    return _MEMO.get(key, lambda: retarget(genes, moves, target, beam, length_cost=length_cost))


def source_key(source: Source) -> str:
    """A short name for a source that stays the same while its sweep and table do (a chain
    remembers by it which sources it has started from, across models)."""
    genes, moves = source
    h = hashlib.sha1(np.ascontiguousarray(genes, dtype=np.int64).tobytes())
    moves = np.ascontiguousarray(moves)
    h.update(moves.dtype.str.encode() + moves.tobytes())
    return h.hexdigest()[:16]


def starts(objective, sources: Sequence[Source], beam: int = BEAM,
           length_cost: float = LENGTH_COST) -> list[tuple[np.ndarray, int]]:
    """Each source's best proposal on the objective's model and its search score, best first
    (one start per source: sweeps of different shapes lead to different basins), scored
    through the objective (the evaluations count); empty without sources. A source that
    proposes only what an earlier one did gives no start of its own. ``beam``,
    ``length_cost``: of the re-expression (:func:`pac_host.search.retarget.retarget`)."""
    return [(x, score) for x, score, _ in starts_by_source(objective, sources, beam,
                                                           length_cost)]


def starts_by_source(objective, sources: Sequence[Source], beam: int = BEAM,
                     length_cost: float = LENGTH_COST) -> list[tuple[np.ndarray, int, int]]:
    """:func:`starts`, each with the index of the source that proposed it."""
    pop, owner = _proposals(sources, objective.loop_table(), objective.budget, beam,
                            length_cost)
    if not len(pop):
        return []
    scores = objective(pop, remember=True)  # every chain on this model scores the same batch
    pop, owner = pop[: len(scores)], owner[: len(scores)]  # a budget may cut the batch
    best: dict[int, int] = {}
    for i, o in enumerate(owner.tolist()):
        if o not in best or scores[i] > scores[best[o]]:
            best[o] = i
    order = sorted(best, key=lambda o: (-int(scores[best[o]]), best[o]))
    return [(pop[best[o]].copy(), int(scores[best[o]]), o) for o in order]
