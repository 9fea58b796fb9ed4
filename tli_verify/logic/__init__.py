"""The logic layer: GR(1) specs (TOML + Spot), BDD game solving (dd/CUDD), task automata."""
