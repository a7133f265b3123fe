"""The PCTL/CTL recursion: formulas in, per-state values and state sets out.

- :mod:`~veribattery.checker.formula.pctl`: the recursion over state, path and
  operator formulas, down to the numeric kernels (:mod:`veribattery.checker.kernels`);
- :mod:`~veribattery.checker.formula.leaves`: operator-free expressions and literals;
- :mod:`~veribattery.checker.formula.share`: the linear systems queries share;
- :mod:`~veribattery.checker.formula.ctl`, :mod:`~veribattery.checker.formula.filters`:
  CTL quantifiers and PRISM's filters;
- :mod:`~veribattery.checker.formula.expression`,
  :mod:`~veribattery.checker.formula.intervals`: arithmetic over operator results, on
  points and on certified intervals.
"""
