"""Symbolic derivation layer (SymPy only; never touches files or compiled code)."""
