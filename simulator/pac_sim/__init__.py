"""`pac-sim`: an emulator of the ServoBot Stamp on a pseudo-terminal, with a simulated world."""
