"""Code generation layer: SymPy expressions → CasADi SX Functions → C files."""
