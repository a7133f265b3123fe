"""``veribattery reproduce``: the seed paper's results beside ours."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import TYPE_CHECKING

import click
from rich.table import Table

from veribattery.cli.output import err, out, user_errors

if TYPE_CHECKING:
    from veribattery.analyses.table3 import Table3Comparison


@click.command("reproduce")
@click.argument("what", type=click.Choice(["table3"]))
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table",
              show_default=True)
def reproduce_command(what: str, output_format: str) -> None:
    """Re-run the seed paper's Table 3 and print it beside the paper's figures."""
    from veribattery.analyses.table3 import reproduce_table3

    with user_errors():
        rows = reproduce_table3(progress=err.print if err.is_terminal else None)
    if output_format == "json":
        click.echo(json.dumps([row.as_dict() for row in rows]))
        return
    print_table3(rows)


def print_table3(rows: Sequence[Table3Comparison]) -> None:
    """Paper vs veribattery, with relative differences."""
    from veribattery.analyses.paper import SOURCE

    table = Table("case", "quantity", "paper", "veribattery", "rel. diff", show_edge=False,
                  title=f"Table 3 — {SOURCE} vs veribattery")
    for row in rows:
        for quantity, paper, ours, diff in row.lines():
            table.add_row(row.paper.case, quantity, paper, ours, diff)
        table.add_section()
    out.print(table)
    out.print(
        "State and transition counts are not expected to match: the paper's model uses a "
        "different encoding (see docs/model-spec.md).", style="dim",
    )

