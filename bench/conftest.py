"""The bench's own checks (``python bench/run.py --only records`` runs them; ``make test`` does
not: records of past runs and the tools that made them are no part of the test suite). The
bench modules import each other by name, as ``bench/run.py`` runs them."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
