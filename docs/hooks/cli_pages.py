"""Reference pages of a command line, from its argparse parser: one section per command and subcommand,
its `--help` as the program prints it, so the page says exactly what the program accepts."""
from __future__ import annotations

import argparse


def subcommands(parser: argparse.ArgumentParser):
    """(name, help, parser) of every subcommand, depth first, in the parser's own order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, child in action.choices.items():
                yield name, helps.get(name, ""), child
                for sub_name, sub_help, grandchild in subcommands(child):
                    yield f"{name} {sub_name}", sub_help, grandchild


def command_page(parser: argparse.ArgumentParser, title: str) -> str:
    lines = [f"# {title}", "", "Generated from the program's argparse parser at every build of this manual.", "",
             _help_block(parser), "", "| Command | What it does |", "|---|---|"]
    commands = list(subcommands(parser))
    lines += [f"| [`{parser.prog} {name}`](#{_anchor(parser.prog, name)}) | {text or ''} |"
              for name, text, _ in commands]
    for name, text, child in commands:
        lines += ["", f"## {parser.prog} {name}", "", text or "", "", _help_block(child)]
    return "\n".join(lines) + "\n"


def _help_block(parser: argparse.ArgumentParser) -> str:
    return "```text\n" + parser.format_help().rstrip() + "\n```"


def _anchor(prog: str, name: str) -> str:
    """The id MkDocs' toc extension gives the heading `prog name`."""
    return f"{prog}-{name}".replace(" ", "-").lower()
