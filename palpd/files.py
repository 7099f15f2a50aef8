"""Writing result files so that a crash never leaves half a file behind."""
from __future__ import annotations

import json
import os
from pathlib import Path

from palpd.errors import PalpdError


def write_json(path: str | Path, data) -> None:
    write_text(path, json.dumps(data, indent=2) + "\n")


def write_text(path: str | Path, text: str) -> None:
    """Write to a temporary file, fsync, then rename over the target."""
    path = Path(path)
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True)
        with temporary.open("w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except OSError as exc:
        raise PalpdError(f"{path}: cannot write: {exc.strerror}") from None
