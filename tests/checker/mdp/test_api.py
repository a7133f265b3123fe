"""The public names of the MDP package."""

from __future__ import annotations

import veribattery.checker.mdp as mdp


def test_exported_members() -> None:
    assert sorted(mdp.__all__) == sorted([
        "MDP", "CertifiedAnswer", "Constraint", "ExactMdpResult", "Front", "FrontSearch",
        "MdpResult", "MdpRewards", "MultiResult",
        "Objective", "Reach", "StepStrategy", "Strategy", "Total",
        "bounded_reach_probability", "cumulative_reward", "exact_probabilities",
        "exact_reach_probability", "exact_reach_reward", "exact_total_reward",
        "induced_chain", "instantaneous_reward", "interval_reach_probability",
        "later_reach_probability", "least_total_at", "multi_achievable", "multi_optimum",
        "next_probability", "pareto_front", "reach_probability", "reach_reward", "total_reward",
    ])
    for name in set(mdp.__all__) - {"Objective"}:  # (a Literal type alias)
        assert getattr(mdp, name).__doc__, name
