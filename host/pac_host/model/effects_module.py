"""Load user-defined effects from a Python file (``--effects-module my_effects.py``).

The file defines its effects with :func:`pac_host.model.effects.register_effect` when it is
imported; every command that takes ``--effects-module`` loads it here, once, before it reads a
table or an ``--effect``, so a user effect is known everywhere a built-in one is (tables,
``--effect``, the simulated world, the coverage simulator, the diagnosis library).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from pac_host.errors import InputError
from pac_host.model.effects import BUILT_IN, EFFECT_SPECS

_LOADED: dict[Path, list[str]] = {}


def load_effects_module(path: str | Path) -> list[str]:
    """Import ``path`` and return the names of the effects it registered.

    Loading the same file again returns the names it registered the first time. Any problem
    (no such file, an error while importing it, no effect registered) is one
    :class:`InputError` line.
    """
    p = Path(path).expanduser().resolve()
    if p in _LOADED:
        return list(_LOADED[p])
    if not p.is_file():
        raise InputError(f"--effects-module: no such file: {path}")
    if p.suffix != ".py":
        raise InputError(f"--effects-module: {path} is not a Python file (.py)")
    before = {n: s for n, s in EFFECT_SPECS.items() if n not in BUILT_IN}
    name = "pac_user_effects_" + "".join(c if c.isalnum() else "_" for c in p.stem)
    spec = importlib.util.spec_from_file_location(name, p)
    mod = importlib.util.module_from_spec(spec)
    try:
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    except InputError as e:
        sys.modules.pop(name, None)
        raise InputError(f"--effects-module {path}: {e}") from None
    except Exception as e:  # the user's code: any error is theirs, reported in one line
        sys.modules.pop(name, None)
        raise InputError(f"--effects-module {path}: {type(e).__name__}: {e}") from None
    added = [n for n, s in EFFECT_SPECS.items() if n not in BUILT_IN and before.get(n) is not s]
    if not added:
        raise InputError(f"--effects-module {path}: defines no effect "
                         "(call pac_host.model.effects.register_effect)")
    _LOADED[p] = added
    return list(added)


def forget_user_effects() -> None:
    """Remove every user-defined effect from the registry (for tests and long-lived hosts)."""
    for name in [n for n in EFFECT_SPECS if n not in BUILT_IN]:
        del EFFECT_SPECS[name]
    _LOADED.clear()
