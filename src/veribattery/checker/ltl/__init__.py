"""LTL on DTMCs and MDPs through deterministic parity automata.

A path formula of full LTL (``G F a``, ``(F a) & (G b)``) is translated into a
deterministic parity automaton over its maximal state subformulas
(:mod:`.propositions`, :mod:`veribattery.checker.automata`); the model and the automaton
run side by side in their product (:mod:`.product`), where the formula holds on a path
exactly when the automaton accepts it: when the path ends in an end component of the
product whose least priority is even (:mod:`.acceptance`). The probability of the formula
is then that of reaching such a component, which the DTMC and MDP solvers certify as
any reachability probability. The DTMC and MDP checkers call in here.
"""
