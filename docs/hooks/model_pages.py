"""Reference pages of the settings and the scene file, from their pydantic models: each key's type, default,
bounds and unit, described by the comments written beside the field in the source (and, for settings with a
sane limit, palpd.settings_bounds' reason), so a new field appears here without anyone writing about it."""
from __future__ import annotations

import ast
import inspect
import io
import json
import textwrap
import tokenize
import typing
from pathlib import Path

from pydantic import BaseModel

UNITS = {"_mm_s2": "mm/s²", "_mm_s": "mm/s", "_n_per_mm": "N/mm", "_n_s_per_mm": "N·s/mm", "_rad_s": "rad/s",
         "_mm": "mm", "_n": "N", "_s": "s", "_hz": "Hz", "_a": "A", "_rad": "rad", "_deg": "°", "_mb": "MB",
         "_kpa": "kPa", "_days": "days"}


def field_comments(model: type[BaseModel]) -> dict[str, str]:
    """{field: the comment on its line, after the comment lines right above it} from the class's source."""
    source = textwrap.dedent(inspect.getsource(model))
    comments = {tok.start[0]: tok.string.lstrip("# ").rstrip()
                for tok in tokenize.generate_tokens(io.StringIO(source).readline) if tok.type == tokenize.COMMENT}
    lines = source.splitlines()
    found = {}
    for node in ast.parse(source).body[0].body:
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            above, line = [], node.lineno - 1
            while line in comments and lines[line - 1].lstrip().startswith("#"):
                above.insert(0, comments[line])
                line -= 1
            found[node.target.id] = " ".join(above + [comments.get(node.lineno, "")]).strip()
    return found


def unit_of(name: str) -> str:
    return next((unit for suffix, unit in UNITS.items() if name.endswith(suffix)), "")


def bounds_of(field) -> str:
    """The field's numeric constraints, as "> 0, ≤ 5.5" (for tuples: of each element)."""
    marks = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤"}
    found = [f"{marks[key]} {value:g}" for meta in _metadata(field) for key in marks
             if (value := getattr(meta, key, None)) is not None]
    return ", ".join(dict.fromkeys(found))  # a pair's two elements carry the same bounds


def _metadata(field):
    yield from field.metadata
    for arg in getattr(field.annotation, "__args__", ()):  # tuple[Positive, Positive]: the elements' bounds
        for meta in getattr(arg, "__metadata__", ()):
            yield from getattr(meta, "metadata", [meta])


def type_of(annotation) -> str:
    """A reader's name for a type: `"raster" | "active"`, `[float, float]`, `str or none`."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return type_of(args[0])
    if origin is typing.Literal:
        return " | ".join(json.dumps(arg) for arg in args)
    if origin is typing.Union:
        return " or ".join("none" if arg is type(None) else type_of(arg) for arg in args)
    if origin in (tuple, list, dict):
        return "[" + ", ".join(type_of(arg) for arg in args) + "]" if origin is tuple else \
            f"{origin.__name__} of {type_of(args[-1])}" if args else origin.__name__
    return getattr(annotation, "__name__", str(annotation))


def default_of(field) -> str:
    if field.is_required():
        return "required"
    default = field.default
    if isinstance(default, BaseModel):
        return "(section)"
    return f"`{json.dumps(default, default=str)}`"


def toml_comments(path: Path) -> dict[str, str]:
    """{"section.key": comment} from a TOML file's trailing comments (config/palpd.toml describes its keys)."""
    found, section = {}, ""
    for line in path.read_text().splitlines():
        head, _, comment = line.partition("#")
        if head.strip().startswith("["):
            section = head.strip().strip("[]")
        elif "=" in head:
            found[f"{section}.{head.split('=')[0].strip()}"] = comment.strip()
    return found


def model_table(model: type[BaseModel], extra_description=lambda name: "", limit=lambda name: None) -> list[str]:
    """One row per field; limit(name) replaces the model's bounds where a tighter rule holds."""
    comments = field_comments(model)
    rows = ["| Key | Type | Default | Bounds | Unit | What it is |", "|---|---|---|---|---|---|"]
    for name, field in model.model_fields.items():
        about = " ".join(filter(None, [comments.get(name, ""), extra_description(name)]))
        rows.append(f"| `{name}` | {_cell(type_of(field.annotation))} | {_cell(default_of(field))} | {limit(name) or bounds_of(field)} "
                    f"| {unit_of(name)} | {_cell(about)} |")
    return rows


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def settings_page() -> str:
    from palpd.config import ENV_PREFIX, Settings
    from palpd.settings_bounds import BOUNDS

    lines = ["# Settings", "", "Generated from the pydantic models in `palpd/config.py` at every build. Every key is "
             "optional; a TOML file (`--config FILE`, `/etc/palpd/palpd.toml` under systemd) sets some, and "
             f"`{ENV_PREFIX}SECTION__KEY` environment variables override the file (values as JSON). Unknown keys "
             "are refused. The shipped `config/palpd.toml` lists every key at its default.", ""]
    shipped_comments = toml_comments(Path(__file__).parents[2] / "config" / "palpd.toml")
    for section, field in Settings.model_fields.items():
        model = field.annotation
        lines += [f"## [{section}]", ""] + ([inspect.getdoc(model), ""] if model.__doc__ else [])

        def reason(name, section=section):
            """The shipped file's comment where the model has none, and the limit's reason."""
            dotted = f"{section}.{name}"
            shipped = "" if field_comments(model).get(name) else shipped_comments.get(dotted, "")
            bound = BOUNDS.get(dotted)
            return " ".join(filter(None, [shipped, f"At most {bound.high:g} {bound.unit}: {bound.why}." if bound else ""]))

        def limit(name, section=section):
            bound = BOUNDS.get(f"{section}.{name}")
            return bound and f"{'≥' if bound.low_inclusive else '>'} {bound.low:g}, ≤ {bound.high:g}"

        lines += model_table(model, reason, limit)
        lines += ["", f"Environment: `{ENV_PREFIX}{section.upper()}__KEY`, e.g. "
                      f"`{ENV_PREFIX}{section.upper()}__{next(iter(model.model_fields)).upper()}`.", ""]
    return "\n".join(lines) + "\n"


def scene_page() -> str:
    from drivers.sim import scene

    lines = ["# Scene files", "", "Generated from the pydantic models in `drivers/sim/scene.py` at every build. A "
             "scene is a TOML file describing the simulated bench: the tissue, its lumps, the sensor. `palpd scenes` "
             "lists the shipped ones; `--scene` takes a name or a path.", ""]
    tables = [("Top level", scene.Scene), ("[tissue]", scene.Tissue), ("[[lump]] (zero or more)", scene.Lump),
              ("[sensor]", scene.Sensor), ("[placement]", scene.Placement),
              ("[faults.KIND] (simulated faults)", scene.FaultAt)]
    for title, model in tables:
        lines += [f"## {title}", ""] + ([inspect.getdoc(model), ""] if model.__doc__ else [])
        lines += model_table(model) + [""]
    return "\n".join(lines) + "\n"
