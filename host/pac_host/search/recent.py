"""A small thread-safe memory of the last results, by key: what a punctuation's search chains
share when each would compute the same thing (a library re-expressed on the model, a batch
scored on the same objective). ``evolve`` searches in a worker thread while the robot walks,
hence the lock; a value is computed outside it, so two threads may both compute one key once.

>>> seen = Recent(2)
>>> seen.get("a", lambda: 1), seen.get("b", lambda: 2), seen.get("a", lambda: 99)
(1, 2, 1)
>>> seen.get("c", lambda: 3), seen.get("b", lambda: 20)  # "b" was the least recently used
(3, 20)
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

V = TypeVar("V")


class Recent(Generic[V]):
    """The values of the last ``size`` keys used, the least recently used dropped first."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._values: OrderedDict[Hashable, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, make: Callable[[], V]) -> V:
        """The value kept under ``key``, or ``make()`` kept there."""
        with self._lock:
            if key in self._values:
                self._values.move_to_end(key)
                return self._values[key]
        value = make()
        with self._lock:
            self._values[key] = value
            self._values.move_to_end(key)
            while len(self._values) > self.size:
                self._values.popitem(last=False)
        return value

    def __len__(self) -> int:
        return len(self._values)

    def clear(self) -> None:
        with self._lock:
            self._values.clear()
