"""`python -m pac_sim`: the same as the `pac-sim` command."""

from pac_sim.cli import main

main()
