"""Which choices may attain a state's optimum, judged soundly from certified bounds."""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.mdp.model import MDP

__all__ = ["may_attain"]

#: The least positive double: a product of two doubles that underflows errs by less.
_TINY = float(np.finfo(np.float64).smallest_subnormal)


def may_attain(mdp: MDP, upper: FloatArray, lower: FloatArray) -> BoolArray:
    """Per choice: whether its value may reach its state's optimum (a maximum), given
    the optimum's certified *upper* and *lower* bounds per state.

    The float product ``P @ upper`` may round below the exact one (1/7 + 4/7 + 2/7
    sums to 0.9999999999999999), and a choice that attains the optimum would then be
    dropped: a lexicographic optimum over the kept choices (the fastest of the safest
    strategies) came out 4.8 where 4.5 attains it. So the product is first raised by
    the rounding bound of a sum of the row's length (and the underflow of each term).
    A choice that only comes close may stay; callers evaluate the strategy they find
    on its own.
    """
    image = mdp.transitions @ upper
    lengths = np.diff(mdp.transitions.indptr)
    slack = image * (lengths + 1) * np.finfo(np.float64).eps + lengths * _TINY
    return np.asarray(image + slack >= lower[mdp.choice_owner], dtype=bool)
