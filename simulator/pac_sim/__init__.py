"""pac_sim: the ServoBot emulator (protocol-level model and the PBASIC interpreter)."""
