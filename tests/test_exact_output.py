"""Exact results in tables: ``p/q ≈ value`` when short, digit counts when long; JSON has all."""

from __future__ import annotations

import json
from fractions import Fraction

from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.cli.output import EXACT_TABLE_CHARS, format_exact

#: Leaves s=0 with probability 1/3 per step: P(F<=60 s=1) = 1 - (2/3)^60, a
#: 29-digit numerator over 3^60 (29 digits) -- too long for a table cell.
MODEL = "dtmc\nmodule m\n  s : [0..1] init 0;\n  [] s=0 -> 1/3 : (s'=1) + 2/3 : (s'=0);\n" \
        "  [] s=1 -> true;\nendmodule\n"
LONG = 1 - Fraction(2, 3) ** 60


def test_short_fractions_print_in_full() -> None:
    assert format_exact("7/10", "0.7") == "7/10 ≈ 0.7"
    assert format_exact("-3", "-3") == "-3"  # an integer: nothing to approximate


def test_long_fractions_print_their_digit_counts() -> None:
    text = f"{LONG.numerator}/{LONG.denominator}"
    assert len(text) > EXACT_TABLE_CHARS
    assert format_exact(text, "0.999") == "≈ 0.999 (p/q: 29/29 digits)"
    assert format_exact("-" + "9" * 50, "-1e50") == "≈ -1e50 (p/q: 50 digits)"


def test_cli_table_is_compact_and_json_is_complete(tmp_path) -> None:
    path = tmp_path / "m.pm"
    path.write_text(MODEL)
    args = ["prism", str(path), "--property", "P=? [ F<=60 s=1 ]", "--exact"]
    table = CliRunner().invoke(cli, args)
    assert table.exit_code == 0, table.output
    assert "(p/q: 29/29 digits)" in table.stdout  # on one line: the table fits 80 columns
    assert "--format json or csv prints every digit" in table.stdout  # the footnote
    assert max(map(len, table.stdout.splitlines())) <= 80
    assert str(LONG.denominator) not in table.stdout
    document = json.loads(CliRunner().invoke(cli, [*args, "--json"]).stdout)
    assert Fraction(document["results"][0]["exact"]) == LONG
