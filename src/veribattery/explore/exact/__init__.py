"""Exact rational arithmetic for ``--exact``: rational evaluation of expressions and the
exact transition probabilities and rewards of a built DTMC.
"""
