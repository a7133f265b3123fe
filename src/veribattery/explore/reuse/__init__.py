"""Reuse across similar models (sweep points): re-evaluating probabilities on a state space
already built, and bisimulation quotients (lumping).
"""
