"""The PCTL/CTL recursion: formulas in, per-state values and state sets out."""
