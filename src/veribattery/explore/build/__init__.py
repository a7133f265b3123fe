"""Breadth-first construction of a DTMC's state space: the builder, its fused layer plans,
successor expansion, state store, memory guard and the domain-wide range check.
"""
