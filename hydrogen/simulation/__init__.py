"""Closed-loop simulation: scenarios, controller runtimes, the loop and its metrics (numpy only)."""
