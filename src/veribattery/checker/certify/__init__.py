"""Certified enclosures: directed rounding, affine fixpoint maps and their certificates."""
