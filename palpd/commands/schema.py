"""palpd schema [TOPIC]: the JSON Schemas of the bus messages and commands."""
from __future__ import annotations

import json

from palpd.errors import UsageError


def add_parser(subparsers):
    schema = subparsers.add_parser("schema", help="print the JSON Schema of bus messages, commands and replies")
    schema.add_argument("topic", nargs="?", metavar="TOPIC",
                        help="an event topic (status, palpation, ...), request, error, CMD.args or reply.CMD "
                             "(e.g. reply.status); default: all")
    return schema


def run(args) -> int:
    from palpd.bus.schemas import all_schemas

    schemas = all_schemas()
    if args.topic is None:
        print(json.dumps(schemas, indent=2))
        return 0
    if args.topic not in schemas:
        raise UsageError(f"unknown topic {args.topic!r}; choose from {', '.join(schemas)}")
    print(json.dumps(schemas[args.topic], indent=2))
    return 0
