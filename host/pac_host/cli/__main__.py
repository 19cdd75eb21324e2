"""`python -m pac_host.cli` runs the pac-host command."""

from pac_host.cli.main import main

main()
