"""Linear systems: restriction to the unknown states, factorisations, triangular and iterative solves, SCC decomposition, exact fallback."""
