"""The protocol package is the lowest layer: it must import and work with the host absent."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pac_host.errors import TOOLKIT_ERRORS, InputError, exit_code
from pac_protocol import errors as perr

ROOT = Path(__file__).resolve().parents[2]

# Import every module of pac_protocol while any import of pac_host fails, then use the codec.
_PROBE = """
import importlib, pkgutil, sys

class _NoHost:
    def find_spec(self, name, path=None, target=None):
        if name == "pac_host" or name.startswith("pac_host."):
            raise ImportError("pac_host is unavailable in this test")
        return None

sys.meta_path.insert(0, _NoHost())
import pac_protocol
names = [m.name for m in pkgutil.iter_modules(pac_protocol.__path__, "pac_protocol.")]
for n in names:
    importlib.import_module(n)
from pac_protocol.errors import PacProtocolError, UsageError
from pac_protocol.frame import Frame, parse_frame
from pac_protocol.link import check_genes
f = Frame(0x01, 7, b"\\x0c\\x0a")
assert parse_frame(f.encode()) == f
try:
    check_genes([(40, 1)])
except UsageError as e:
    assert isinstance(e, PacProtocolError)
else:
    raise SystemExit("check_genes accepted gait id 40")
assert not any(m == "pac_host" or m.startswith("pac_host.") for m in sys.modules)
print(len(names))
"""


def test_protocol_imports_without_the_host():
    r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                       cwd=ROOT, timeout=60)
    assert r.returncode == 0, r.stderr
    assert int(r.stdout) >= 6  # every module of the package was imported


def test_no_host_import_in_protocol_sources():
    hits = [p.name for p in (ROOT / "protocol" / "pac_protocol").rglob("*.py")
            if "pac_host" in p.read_text()]
    assert hits == []


@pytest.mark.parametrize(("error", "code"), [
    (perr.NoAnswer("x"), 1), (perr.BadCheck("x"), 1), (perr.StampReset("x"), 1),
    (perr.PortError("x"), 2), (perr.UsageError("x"), 2), (InputError("x"), 2),
])
def test_protocol_errors_map_to_exit_codes(error, code):
    assert isinstance(error, TOOLKIT_ERRORS)
    assert exit_code(error) == code
