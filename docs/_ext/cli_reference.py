"""``.. cli-reference::``: every command's ``--help``, read from the click objects.

The directive walks :data:`veribattery.cli.cli` with click's own context (so lazily
imported commands are loaded as ``--help`` loads them) and emits one section per
command and subcommand, holding exactly what ``veribattery ... --help`` prints.
"""

from __future__ import annotations

from collections.abc import Iterator

import click
from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

#: Help is laid out at this width, as in an 80-column terminal.
WIDTH = 80
#: Section underlines by depth below the page title: commands, then subcommands.
UNDERLINES = ("-", "~")


def _commands(
    command: click.Command, parent: click.Context | None, name: str
) -> Iterator[tuple[int, click.Context]]:
    """Each command's context, depth first, in the order ``--help`` lists them."""
    ctx = click.Context(command, parent=parent, info_name=name,
                        terminal_width=WIDTH, max_content_width=WIDTH)
    yield (0 if parent is None else len(ctx.command_path.split()) - 1), ctx
    if isinstance(command, click.Group):
        for sub in command.list_commands(ctx):
            child = command.get_command(ctx, sub)
            if child is not None and not child.hidden:
                yield from _commands(child, ctx, sub)


def _section(depth: int, ctx: click.Context) -> list[str]:
    """reST for one command: a title (except for the root) and its help, verbatim."""
    lines: list[str] = []
    if depth > 0:
        title = f"``{ctx.command_path}``"
        lines += [title, UNDERLINES[min(depth, len(UNDERLINES)) - 1] * len(title), ""]
        summary = ctx.command.get_short_help_str(limit=WIDTH)
        if summary:
            lines += [summary.replace("*", r"\*").replace("`", r"\`"), ""]
    lines += [".. code-block:: text", ""]
    lines += [f"   {line}".rstrip() for line in ctx.command.get_help(ctx).splitlines()]
    return [*lines, ""]


class CliReference(SphinxDirective):
    """Insert the help of ``veribattery`` and of every command below it."""

    def run(self) -> list[nodes.Node]:
        from veribattery.cli import cli

        text: list[str] = []
        for depth, ctx in _commands(cli, None, "veribattery"):
            text += _section(depth, ctx)
        container = nodes.section()
        nested_parse_with_titles(self.state, StringList(text, source="veribattery --help"),
                                 container)
        return list(container.children)


def setup(app: Sphinx) -> dict[str, object]:
    app.add_directive("cli-reference", CliReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
