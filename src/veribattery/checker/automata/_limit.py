"""The one error of the package: a construction that outgrows its state budget.

It lives apart from :mod:`.parity` so that each stage (tableau, determinisation,
state-based conversion) can check the budget without importing the stage after it.
"""

from __future__ import annotations


class AutomatonTooLarge(ValueError):
    """The automaton of a formula would have more states than the caller allows."""

    def __init__(self, what: str, reached: int, limit: int) -> None:
        super().__init__(f"the {what} reached {reached} states, over the limit "
                         f"max_states={limit}; simplify the LTL formula or raise max_states")
        #: The stage, the states it reached, and the budget.
        self.what, self.reached, self.limit = what, reached, limit


def check_size(reached: int, limit: int, what: str) -> None:
    """Raise :class:`AutomatonTooLarge` if ``reached`` states exceed ``limit``."""
    if reached > limit:
        raise AutomatonTooLarge(what, reached, limit)
