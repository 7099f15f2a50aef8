"""Driver exceptions, one per lifecycle phase (as python-can does), plus one-line validation messages."""
from __future__ import annotations


class DriverError(Exception):
    """Base of every error raised by drivers/."""


class DriverInitializationError(DriverError):
    """A device or backend could not be opened or configured."""


class DriverOperationError(DriverError):
    """A device failed while in use."""


class DriverTimeoutError(DriverError, TimeoutError):
    """A device did not answer within its timeout."""


def describe_validation_error(source: str, error) -> str:
    """One line for a pydantic ValidationError: the source, the dotted field path, what was expected."""
    first = error.errors()[0]
    path = ".".join(str(part) for part in first["loc"]) or "(top level)"
    message = first["msg"]
    if first["type"] == "extra_forbidden":
        message = "unknown key"
    elif first["type"] == "missing":
        message = "required key is missing"
    elif "input" in first and not isinstance(first["input"], dict):
        message += f" (got {first['input']!r})"
    more = len(error.errors()) - 1
    suffix = f" (and {more} more problem{'s' if more > 1 else ''})" if more else ""
    return f"{source}: {path}: {message}{suffix}"
