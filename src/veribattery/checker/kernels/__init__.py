"""Numeric kernels: transition matrices and state masks in, certified bounds out."""
