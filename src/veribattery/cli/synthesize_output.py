"""What ``synthesize`` prints: the table at a terminal, one JSON object, or CSV rows.

Certified values (Pmax, BS1's, the table strategy's, the fastest strategies') are
printed as ``check`` prints results, to 12 significant digits with ``± error`` where
the certified error shows; a fastest strategy that only a linear programme answered
(not certified) is printed as ``≈`` with 7 significant digits.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import click

from veribattery.cli.output import format_value, json_value, out, print_dim, print_timings
from veribattery.cli.tables import fit_text, print_table

if TYPE_CHECKING:
    from veribattery.synthesis.fastest import Fastest
    from veribattery.synthesis.model import Certified
    from veribattery.synthesis.session import SynthesisResult
    from veribattery.synthesis.thresholds import ThresholdRow

__all__ = ["print_csv", "print_json", "print_table_output", "synthesis_json"]

#: Rows of the threshold table shown at a terminal, per kind (non-thresholds, BS1 apart).
SHOWN_ROWS = 10
#: Significant digits of a linear programme's answer.
LP_DIGITS = 7


def certified_text(value: Certified) -> str:
    """*value* to 12 significant digits, ``± error`` when the certified error shows."""
    text = format_value(value.value)
    error = value.error
    if not math.isfinite(value.value) or error <= 0 or value.value == 0:
        return text
    half_last = 0.5 * 10.0 ** (math.floor(math.log10(abs(value.value))) - 11)
    return f"{text} ± {error:.2g}" if error >= half_last else text


def lp_text(value: float | None) -> str:
    """A linear programme's answer: ``≈ 628.545`` (``—`` where there is none)."""
    return "—" if value is None else f"≈ {value:.{LP_DIGITS}g}"


def print_table_output(result: SynthesisResult) -> None:
    """Sizes, the optimum beside BS1, the fastest strategies, the threshold rows."""
    size = result.size
    click.echo(f"Mission MDP: {size.states:,} states, {size.choices:,} choices, "
               f"{size.transitions:,} transitions")
    _print_comparison(result)
    if result.fastest:
        click.echo()
        _print_fastest(result)
    click.echo()
    _print_strategy(result)
    print_timings(result.timings_s)


def _print_comparison(result: SynthesisResult) -> None:
    bs1, own = result.bs1, result.strategy
    rows = [("P(success)", certified_text(result.p_success_max),
             certified_text(bs1.p_success)),
            ("E[mission time] (min)", certified_text(own.exp_mission_time),
             certified_text(bs1.exp_mission_time)),
            ("E[recharges]", certified_text(own.exp_recharges),
             certified_text(bs1.exp_recharges))]
    click.echo()
    print_table(("", "optimum (Pmax)", f"BS1 (safe_t {_fraction(bs1.safe_t)})"), rows)
    print_dim(fit_text("Pmax: the best P(success) of any return policy. Its times: of the "
                       "fastest strategy that attains it (the threshold table below). "
                       "Times and recharges count failed missions too."))


def _print_fastest(result: SynthesisResult) -> None:
    rows = [(f.requirement, _answer_text(f, f.exp_mission_time, f.time_bounds),
             _answer_text(f, f.exp_recharges, f.recharges_bounds), _versus_bs1(result, f))
            for f in result.fastest]
    print_table(("fastest with", "E[time] (min)", "E[recharges]", "vs BS1"), rows,
                title="The fastest strategy that meets each requirement:")
    if any(not f.certified for f in result.fastest):
        print_dim(fit_text("≈: linear programmes solved in floating point (HiGHS), not "
                           "certified: good to about 1e-7. Such a strategy may randomise."))
    if any(f.certified and f.achievable for f in result.fastest):
        print_dim(fit_text("Certified: the least expected time from the Pareto front "
                           "(weighted sums), attained by a strategy that picks one of two "
                           "deterministic strategies once at the start; its recharges are "
                           "that strategy's. At Pmax: the strategy of the table below."))
    if any(f.achievable and f.p > result.bs1.p_success.value for f in result.fastest):
        print_dim(fit_text("*: BS1 itself does not meet this requirement."))
    for answer in result.fastest:
        if not answer.achievable:
            out.print(f"[bold red]FAIL[/] {answer.requirement}: no strategy meets it; the "
                      f"best P(success) is {format_value(result.p_success_max.value)} (Pmax)",
                      highlight=False)


def _answer_text(answer: Fastest, value: float | None,
                 bounds: tuple[float, float] | None = None) -> str:
    if answer.certified and value is not None:
        if bounds is None:
            return format_value(value)
        from veribattery.synthesis.model import Certified

        return certified_text(Certified(value, *bounds))
    return lp_text(value)


def _versus_bs1(result: SynthesisResult, answer: Fastest) -> str:
    if not answer.achievable:
        return "none meets it"
    gain = result.speedup(answer)
    if gain is None:
        return "—"
    star = "*" if answer.p > result.bs1.p_success.value else ""
    word = "faster" if gain >= 0 else "slower"
    return f"{abs(gain):.1%} {word}{star}"


def _print_strategy(result: SynthesisResult) -> None:
    table, own = result.table, result.strategy
    bolder, warier = _bolder(table.rows), _warier(table.rows)
    click.echo(fit_text(
        f"The strategy (safest, then fastest) reaches {own.reached.size:,} states; its "
        f"threshold table has {len(table.rows):,} rows, {len(table.non_thresholds):,} of "
        f"them not a threshold. Where BS1 would decide otherwise at a charge the strategy "
        f"meets: {len(bolder):,} rows where it goes on below BS1's threshold, "
        f"{len(warier):,} where it turns back at or above it. Charges in units of "
        f"{table.charge_unit_ah} Ah."))
    for title, rows in (("Not a threshold:", table.non_thresholds),
                        ("Goes on where BS1 would not (furthest below BS1 first):", bolder),
                        ("Turns back where BS1 would go on (furthest above first):", warier)):
        if rows:
            click.echo()
            print_table(("decision", "cell", "done", "wind", "rc", "level", "goes on ≥",
                         "back ≤", "BS1 ≥", "threshold"),
                        [_row(r) for r in rows[:SHOWN_ROWS]], keys=2, title=title)
    print_dim(fit_text("The whole table: --csv FILE, or --format json."))


def _bolder(rows: Sequence[ThresholdRow]) -> list[ThresholdRow]:
    """Rows where the strategy goes on at a charge below BS1's least (or BS1 never
    goes on), furthest below first."""
    def below(row: ThresholdRow) -> int:
        assert row.least_go_on is not None
        top = row.level_to + 1 if row.bs1_least_go_on is None else row.bs1_least_go_on
        return top - row.least_go_on

    found = [r for r in rows if r.least_go_on is not None and below(r) > 0]
    return sorted(found, key=below, reverse=True)


def _warier(rows: Sequence[ThresholdRow]) -> list[ThresholdRow]:
    """Rows where the strategy turns back at a charge from which BS1 goes on, furthest
    above first."""
    def above(row: ThresholdRow) -> int:
        assert row.greatest_turn_back is not None and row.bs1_least_go_on is not None
        return row.greatest_turn_back - row.bs1_least_go_on + 1

    found = [r for r in rows if r.greatest_turn_back is not None
             and r.bs1_least_go_on is not None and above(r) > 0]
    return sorted(found, key=above, reverse=True)


def _row(row: ThresholdRow) -> tuple[str, ...]:
    return (row.decision, f"[{row.cell[0]},{row.cell[1]}]", str(row.turbines_done), row.wind,
            str(row.recharges), row.level, _charge(row.least_go_on),
            _charge(row.greatest_turn_back), _charge(row.bs1_least_go_on),
            "yes" if row.threshold else "NO")


def _charge(value: int | None) -> str:
    return "—" if value is None else str(value)


def _fraction(value: object) -> str:
    from veribattery.config.exact import show

    return str(show(value))


def synthesis_json(result: SynthesisResult) -> dict[str, object]:
    """The ``synthesize --format json`` document."""
    from veribattery.synthesis import threshold_json
    from veribattery.synthesis.fastest import LP_TOLERANCE

    bs1, own = result.bs1, result.strategy
    certified = {"p_success_max": result.p_success_max, "bs1_p_success": bs1.p_success,
                 "bs1_exp_mission_time": bs1.exp_mission_time,
                 "bs1_exp_recharges": bs1.exp_recharges, "strategy_p_success": own.p_success,
                 "strategy_exp_mission_time": own.exp_mission_time,
                 "strategy_exp_recharges": own.exp_recharges}
    return {
        "model": {"states": result.size.states, "choices": result.size.choices,
                  "transitions": result.size.transitions},
        "results": {"p_success_max": json_value(result.p_success_max.value)},
        "bounds": {name: [json_value(c.lower), json_value(c.upper)]
                   for name, c in certified.items()},
        "bs1": {"safe_t": _fraction(bs1.safe_t), "p_success": json_value(bs1.p_success.value),
                "exp_mission_time": json_value(bs1.exp_mission_time.value),
                "exp_recharges": json_value(bs1.exp_recharges.value), "states": bs1.states},
        "fastest": [_fastest_json(result, f) for f in result.fastest],
        "lp_tolerance": LP_TOLERANCE,
        "strategy": {"p_success": json_value(own.p_success.value),
                     "exp_mission_time": json_value(own.exp_mission_time.value),
                     "exp_recharges": json_value(own.exp_recharges.value),
                     "states_reached": int(own.reached.size), **threshold_json(result.table)},
        "front": [{"p": p.p, "exp_mission_time": p.exp_mission_time} for p in result.front],
        "bs1_front": [{"safe_t": _fraction(b.safe_t), "p_success": b.p_success,
                       "exp_mission_time": b.exp_mission_time} for b in result.bs1_front],
        "timings_s": {k: round(v, 6) for k, v in result.timings_s.items()},
    }


def _fastest_json(result: SynthesisResult, answer: Fastest) -> dict[str, object]:
    return {"requirement": answer.requirement, "p": answer.p, "achievable": answer.achievable,
            "certified": answer.certified,
            "exp_mission_time": answer.exp_mission_time, "exp_recharges": answer.exp_recharges,
            "exp_mission_time_bounds": _pair(answer.time_bounds),
            "exp_recharges_bounds": _pair(answer.recharges_bounds),
            "mixing": answer.mixing, "weighted_solves": answer.solves,
            "speedup_vs_bs1": result.speedup(answer),
            "best_p_success": json_value(result.p_success_max.value)}


def _pair(bounds: tuple[float, float] | None) -> list[object] | None:
    return None if bounds is None else [json_value(bounds[0]), json_value(bounds[1])]


def print_json(result: SynthesisResult) -> None:
    """One JSON object on stdout."""
    click.echo(json.dumps(synthesis_json(result)))


def print_csv(result: SynthesisResult) -> None:
    """``quantity,requirement,value,lower,upper`` rows, full precision (a linear
    programme's answer, or one at Pmax, has no bounds; an unmet requirement no value)."""
    bs1, own = result.bs1, result.strategy
    click.echo("quantity,requirement,value,lower,upper")
    for name, c in (("p_success_max", result.p_success_max),
                    ("bs1_p_success", bs1.p_success),
                    ("bs1_exp_mission_time", bs1.exp_mission_time),
                    ("bs1_exp_recharges", bs1.exp_recharges),
                    ("strategy_p_success", own.p_success),
                    ("strategy_exp_mission_time", own.exp_mission_time),
                    ("strategy_exp_recharges", own.exp_recharges)):
        click.echo(f"{name},,{c.value!r},{c.lower!r},{c.upper!r}")
    for f in result.fastest:
        for name, value, bounds in (
                ("fastest_exp_mission_time", f.exp_mission_time, f.time_bounds),
                ("fastest_exp_recharges", f.exp_recharges, f.recharges_bounds)):
            low, high = ("", "") if bounds is None else (repr(bounds[0]), repr(bounds[1]))
            click.echo(f"{name},{f.requirement},{'' if value is None else repr(value)},"
                       f"{low},{high}")
