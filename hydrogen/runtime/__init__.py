"""Runtime layer: compile generated C, load it with ctypes, call it (numpy only, no SymPy)."""
