"""The settings a tradeoff sweep compares; each is scanned on every scene × seed.

A grid file (TOML) lists them as `[[run]]` tables:

    [[run]]
    strategy = "active"          # active | raster | random
    palpation = "discrete"       # discrete (the default) | sliding (any strategy)
    palpations = 40              # the budget: active's learner.max_palpations, the raster's or random count
                                 # (sliding: paths, a raster's rows)
    settings = { learner = { tolerance_mm = 1.0 } }   # any settings, as in palpd.toml
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from drivers.errors import describe_validation_error
from drivers.tomlfile import read_toml
from palpd.errors import UsageError


class GridEntry(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    strategy: Literal["active", "raster", "random"]
    palpation: Literal["discrete", "sliding"] = "discrete"
    palpations: Annotated[int, Field(ge=1, le=10000)] | None = None
    settings: dict[str, dict[str, Any]] = {}

    @property
    def label(self) -> str:
        """The `setting` column: what differs from the defaults, e.g. `tolerance_mm=1.0` or `n=25`."""
        parts = [f"{key}={value}" for section in self.settings.values() for key, value in section.items()]
        if self.palpations is not None:
            parts.insert(0, f"n={self.palpations}")
        return ";".join(parts) or "default"


def _entries(*rows: dict) -> list[GridEntry]:
    return [GridEntry(**row) for row in rows]


# The knobs a user turns: active's stop rule (tolerance, confidence; coverage and the closer look beside lumps
# found together, off: lumps left unfelt against palpations) and indentation (depth, speed) at its default
# budget; raster and random at counts from a quick look to the seed paper's 81; sliding at speeds from 10 to
# 40 mm/s (the modulation faster with the speed: a reading every 2.5-4 mm of path), as a raster and along
# random paths.
DEFAULT_GRID = _entries(
    {"strategy": "active"},
    *({"strategy": "active", "settings": {"learner": {"tolerance_mm": t}}} for t in (0.25, 1.0, 2.0)),
    *({"strategy": "active", "settings": {"learner": {"confidence": c}}} for c in (0.7, 0.99)),
    *({"strategy": "active", "settings": {"learner": {"coverage_mm": c}}} for c in (11.0, 14.0)),
    {"strategy": "active", "settings": {"learner": {"satellite_reach": 0.0}}},
    *({"strategy": "active", "settings": {"palpation": {"depth_mm": d}}} for d in (2.0, 6.0)),
    *({"strategy": "active", "settings": {"palpation": {"speed_mm_s": v}}} for v in (5.0, 20.0)),
    *({"strategy": "raster", "palpations": n} for n in (9, 25, 49, 81)),
    *({"strategy": "random", "palpations": n} for n in (9, 25, 49)),
    {"strategy": "active", "palpation": "sliding"},
    *({"strategy": "active", "palpation": "sliding",
       "settings": {"palpation": {"sliding_speed_mm_s": v, "modulation_hz": hz}}} for v, hz in ((10.0, 4.0),
                                                                                             (20.0, 8.0))),
    {"strategy": "active", "palpation": "sliding", "settings": {"palpation": {"sliding_speed_mm_s": 40.0}}},
    {"strategy": "raster", "palpation": "sliding", "palpations": 7},
    {"strategy": "random", "palpation": "sliding", "palpations": 7},
)


@dataclass(frozen=True)
class Run:
    """One task: a grid entry on one scene with one seed (the scan's and the simulated world's), with the
    settings validated here, before any task goes out."""

    scene: Any  # drivers.sim.scene.Scene (its map, if any, must be readable where the task runs)
    seed: int
    entry: GridEntry
    settings: Any  # palpd.config.Settings

    @property
    def name(self) -> str:
        return f"{self.scene.name} seed {self.seed} {self.entry.strategy} {self.entry.palpation} {self.entry.label}"


def load_grid(path: str | Path) -> list[GridEntry]:
    data = read_toml(Path(path), "tradeoff grid", UsageError)
    rows = data.get("run")
    if not isinstance(rows, list) or not rows or set(data) != {"run"}:
        raise UsageError(f"{path}: a tradeoff grid is a list of [[run]] tables, and nothing else")
    entries = []
    for number, row in enumerate(rows, 1):
        try:
            entries.append(GridEntry.model_validate(row))
        except ValidationError as exc:
            raise UsageError(describe_validation_error(f"{path}: run {number}", exc)) from None
    return entries


def runs(scenes: list, seeds: int, grid: list[GridEntry], base) -> list[Run]:
    """Every entry on every scene × seed, on the base settings (palpd.config.Settings)."""
    return [Run(scene, seed, entry, _settings(base, entry, seed)) for scene in scenes for seed in range(seeds)
            for entry in grid]


def _settings(base, entry: GridEntry, seed: int):
    from palpd.errors import ConfigError

    try:
        sections = entry.settings
        return base.updated(**{**sections, "scan": {**sections.get("scan", {}), "strategy": entry.strategy, "seed": seed},
                               "palpation": {**sections.get("palpation", {}), "mode": entry.palpation}})
    except (ConfigError, KeyError) as exc:
        raise UsageError(f"tradeoff grid, run {entry.strategy} {entry.label}: {exc}") from None
