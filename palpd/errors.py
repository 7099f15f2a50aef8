"""palpd's exceptions; each carries the exit status the command line uses for it."""
from __future__ import annotations

EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_UNDETERMINED = 3  # a scan whose budget ran out before the evidence decided (verdict `undetermined`)
EXIT_CONFIG = 78  # sysexits EX_CONFIG: systemd must not restart a daemon whose config is wrong


class PalpdError(Exception):
    exit_code = EXIT_FAILURE


class ConfigError(PalpdError):
    exit_code = EXIT_CONFIG


class UsageError(PalpdError):
    exit_code = EXIT_USAGE


class StorageError(PalpdError):
    """A file could not be written because the storage failed (ENOSPC, EIO, EROFS, EDQUOT): the daemon makes it a
    `storage` fault, never an exit. `errno` says which."""

    def __init__(self, message: str, errno: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno


class ScanFault(PalpdError):
    """The safety supervisor stopped the robot; the fault is latched until reset."""
