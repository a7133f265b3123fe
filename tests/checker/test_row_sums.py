"""certify.sums_at_most_one: which rows of a matrix sum to at most 1, exactly.

The step-bounded kernels may take the unbounded until as a ceiling only where every
moving row does (``docs/numerics.md``); a row written ``0.9 + 0.1`` sums to
``1 + 2^-55`` as stored, one written ``1/3`` thrice to less than 1.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery.checker.certify import sums_at_most_one


def test_rows_summing_to_at_most_one_are_told_exactly() -> None:
    """The float sum's enclosure decides most rows; those it leaves open (every row
    that sums to 1 exactly) are summed in rationals."""
    rows = [[0.5, 0.5], [0.1, 0.2, 0.7], [1 / 3] * 3, [0.3] * 3 + [0.1], [], [1.0],
            [0.9, 0.1], [0.6, 0.6], [0.1] * 10, [1.0, 2.0**-60], [0.5, 0.25, 0.25]]
    data = [p for row in rows for p in row]
    columns = [j for row in rows for j in range(len(row))]
    indptr = np.cumsum([0] + [len(row) for row in rows])
    M = sp.csr_matrix((data, columns, indptr), shape=(len(rows), 12))
    found = sums_at_most_one(M).tolist()
    assert found == [sum(map(Fraction, row)) <= 1 for row in rows]
    assert found == [True, True, True, True, True, True, False, False, False, False, True]
