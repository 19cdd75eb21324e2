"""`pac-host` loads its commands lazily: listing them (--help, completing a name) imports no
command module and nothing heavy; the map of commands agrees with the commands themselves.
(How fast that is, is bench/bench_cli.py's.)"""

from __future__ import annotations

import json
import subprocess
import sys

import click

from pac_host.cli.main import COMMANDS, load_command

HEAVY = ("numpy", "scipy", "matplotlib", "numba", "dask", "cv2", "serial")


def _imported_after(code: str) -> list[str]:
    """Modules of interest in sys.modules after running ``code`` in a fresh interpreter."""
    probe = (f"{code}\nimport json, sys\n"
             "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
             f"{HEAVY!r} or m.startswith('pac_host.cli.'))))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_importing_the_cli_imports_nothing_heavy():
    assert _imported_after("import pac_host, pac_host.cli.main") == ["pac_host.cli.main"]


def test_help_and_completing_a_name_import_no_command():
    help_run = ("from pac_host.cli.main import main\n"
                "try:\n    main(['--help'])\nexcept SystemExit:\n    pass")
    assert _imported_after(help_run) == ["pac_host.cli.main"]
    complete = ("import os\nos.environ.update(_PAC_HOST_COMPLETE='bash_complete', "
                "COMP_WORDS='pac-host e', COMP_CWORD='1')\n"
                "from pac_host.cli.main import main\n"
                "try:\n    main(prog_name='pac-host')\nexcept SystemExit:\n    pass")
    out = subprocess.run([sys.executable, "-c", complete], capture_output=True, text=True)
    assert out.stdout.split() == ["plain,evolve", "plain,experiment"]
    assert _imported_after(complete) == ["pac_host.cli.main"]


def test_the_map_agrees_with_each_commands_own_help():
    for name, (_, short) in COMMANDS.items():
        cmd = load_command(name)
        assert isinstance(cmd, click.Command) and cmd.name == name
        assert cmd.get_short_help_str(limit=1000) == short, name


def test_help_lists_every_command_with_its_line():
    from click.testing import CliRunner

    from pac_host.cli.main import main

    text = CliRunner().invoke(main, ["--help"]).output
    listed = [line.split()[0] for line in text.split("Commands:")[1].splitlines()
              if line.startswith("  ") and not line.startswith("   ")]
    assert listed == sorted(COMMANDS)
    assert "Diagnose the gap between a model and observed runs." in text
