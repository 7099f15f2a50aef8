"""The bus reference page, from the published JSON Schemas (`palpd schema`): every event, the request and error
envelopes, each command's arguments and its reply, as a table of fields and the schema itself."""
from __future__ import annotations

import json

GROUPS = [("Events (PUB topics)", lambda name: "." not in name and name not in ("request", "error")),
          ("Envelopes", lambda name: name in ("request", "error")),
          ("Command arguments", lambda name: name.endswith(".args")),
          ("Replies", lambda name: name.startswith("reply."))]


def bus_page() -> str:
    from palpd.bus.schemas import all_schemas

    schemas = all_schemas()
    lines = ["# Bus messages", "", "Generated from the JSON Schemas palpd publishes (`palpd schema`, "
             "`palpd/bus/schemas.py`) at every build. Framing, endpoints and security: "
             "[the protocol](../protocol.md).", ""]
    for title, belongs in GROUPS:
        lines += [f"## {title}", ""]
        for name, schema in schemas.items():
            if belongs(name):
                lines += schema_section(name, schema, schemas)
    return "\n".join(lines) + "\n"


def schema_section(name: str, schema: dict, schemas: dict) -> list[str]:
    lines = [f"### `{name}`", "", " ".join(schema.get("description", "").split()), ""]
    properties = schema.get("properties", {})
    if properties:
        required = set(schema.get("required", []))
        lines += ["| Field | Type | Required | What it is |", "|---|---|---|---|"]
        lines += [f"| `{field}` | {_cell(type_text(spec))} | {'yes' if field in required else ''} "
                  f"| {_cell(' '.join(spec.get('description', '').split()))} |" for field, spec in properties.items()]
        lines.append("")
    lines += [f'??? note "JSON Schema of `{name}`"', "", "    ```json"]
    lines += ["    " + line for line in json.dumps(schema, indent=2).splitlines()]
    return lines + ["    ```", ""]


def type_text(spec: dict) -> str:
    """A short type: `integer`, `"ready" | "fault"`, `array of Probe`, `Lump or null`."""
    if "enum" in spec:
        return " | ".join(json.dumps(value) for value in spec["enum"])
    if "$ref" in spec:
        return spec["$ref"].rsplit("/", 1)[-1]
    if "anyOf" in spec:
        return " or ".join(type_text(option) for option in spec["anyOf"])
    if spec.get("type") == "array":
        items = spec.get("items") or spec.get("prefixItems")
        return "array of " + (type_text(items) if isinstance(items, dict) else "values")
    return str(spec.get("type", "any"))


def _cell(text: str) -> str:
    return text.replace("|", "\\|")
