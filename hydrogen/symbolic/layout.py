"""Controller state layouts: plain data, shared by the derivation and the (SymPy-free) runtime."""

__all__ = ["STATE_LAYOUT"]

#: Controller name -> [(state block, size)] in the order of the controller state xc.
STATE_LAYOUT = {
    "backstepping": [],
    "adaptive-robust": [("z", 6), ("theta_hat", 4), ("gamma1_hat", 6), ("gamma2_hat", 6)],
    "adaptive-observer": [("q_hat", 6), ("z", 6), ("theta_hat", 4), ("gamma1_hat", 6), ("gamma2_hat", 6)],
    "p": [],
}
