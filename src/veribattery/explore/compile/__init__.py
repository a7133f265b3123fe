"""Compile PRISM expressions into numpy functions over many states at once: operators,
lookup tables, chains, interval bounds, compiled commands.
"""
