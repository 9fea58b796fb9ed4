"""Learned dynamical systems: GMM mixing, LPV-DS, Lyapunov SDPs, the BC baseline."""
