"""Analyses built on the pipeline: reproductions of the seed paper's results."""
