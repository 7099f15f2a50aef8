"""`palpd` on a disk that fills up: run as `python tests/full_disk.py serve ...` in place of `python -m palpd`.

The fault-injection seam: palpd opens every session file through palpd.files.open_for_writing and asks how
full the disk is through palpd.files.disk_usage. Here both are replaced, from the environment:
  PALPD_TEST_DISK_BYTES  the disk holds this many bytes written through the seam; a write beyond them writes
                         what fits and raises ENOSPC, as a full filesystem does
  PALPD_TEST_DISK_FILES  only files whose name matches this glob count and fail (default: every file)
  PALPD_TEST_DISK_FREED  a path: once it exists, the disk has room again (an operator freed space)
  PALPD_TEST_DISK_ERRNO  the error to raise instead of ENOSPC, by name (e.g. EIO, EROFS)
No filesystem is mounted: the tests run anywhere, unprivileged.
"""
from __future__ import annotations

import errno
import fnmatch
import os
import sys
from pathlib import Path


class Disk:
    def __init__(self, capacity: int, pattern: str, freed: str, error: int) -> None:
        self.capacity, self.pattern, self.freed, self.error = capacity, pattern, freed, error
        self.used = 0

    def full(self) -> bool:
        return not (self.freed and os.path.exists(self.freed))

    def take(self, path: str, size: int) -> int:
        """How much of a write of `size` bytes to `path` fits; raises once nothing does."""
        if not fnmatch.fnmatch(Path(path).name, self.pattern) or not self.full():
            return size
        room = max(self.capacity - self.used, 0)
        if size > room and (room == 0 or self.error != errno.ENOSPC):
            raise OSError(self.error, os.strerror(self.error), str(path))
        self.used += min(size, room)
        return min(size, room)


class FillingFile:
    """A real file whose writes stop with ENOSPC once the disk is full (what fitted is written)."""

    def __init__(self, disk: Disk, path, mode: str) -> None:
        self._disk, self._path = disk, str(path)
        if "w" in mode or "a" in mode:
            disk.take(self._path, 0)  # a read-only filesystem refuses the open itself
        self._file = open(path, mode)

    def write(self, data) -> int:
        fits = self._disk.take(self._path, len(data))
        written = self._file.write(data[:fits])
        if fits < len(data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self._path)
        return written

    def __getattr__(self, name):
        return getattr(self._file, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._file.close()


def install() -> None:
    import palpd.files

    disk = Disk(int(os.environ.get("PALPD_TEST_DISK_BYTES", "0")), os.environ.get("PALPD_TEST_DISK_FILES", "*"),
                os.environ.get("PALPD_TEST_DISK_FREED", ""), getattr(errno, os.environ.get("PALPD_TEST_DISK_ERRNO",
                                                                                             "ENOSPC")))
    real_usage = palpd.files.disk_usage

    def disk_usage(path):
        if not disk.full():
            return real_usage(path)
        return (disk.capacity, min(disk.used, disk.capacity), max(disk.capacity - disk.used, 0))

    palpd.files.open_for_writing = lambda path, mode="w": FillingFile(disk, path, mode)
    palpd.files.disk_usage = disk_usage


if __name__ == "__main__":
    install()
    from palpd.cli import main

    sys.exit(main(sys.argv[1:]))
