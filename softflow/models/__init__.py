"""Inverse models u_t = g(x_{t-K+1}, ..., x_t, x_{t+1}): deterministic baselines and the RF family."""
