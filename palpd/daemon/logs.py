"""The daemon's logging: stdlib logging on stderr, in the form journald reads when systemd runs palpd.

Under systemd (stderr is the journal stream named by $JOURNAL_STREAM) each line
is `<PRIORITY>logger: message`: journald strips the sd-daemon prefix into the
entry's priority and stamps the time itself. Anywhere else a line carries its
own time and level.
"""
from __future__ import annotations

import logging
import os
import sys

LEVELS = ("debug", "info", "warning", "error")
SYSLOG_PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}


class JournalFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        priority = SYSLOG_PRIORITY.get(record.levelno, 6)
        return f"<{priority}>{record.name}: {record.getMessage()}"


def under_journal(stream=None, environ=None) -> bool:
    """True when the stream is the journal's: $JOURNAL_STREAM is its "device:inode" (systemd.exec(5))."""
    stream = stream or sys.stderr
    expected = (environ if environ is not None else os.environ).get("JOURNAL_STREAM", "")
    try:
        info = os.fstat(stream.fileno())
    except (OSError, ValueError, AttributeError):
        return False
    return expected == f"{info.st_dev}:{info.st_ino}"


def setup_logging(level: str = "info", stream=None) -> logging.Logger:
    """Configure the `palpd` logger tree once for the daemon; returns it."""
    stream = stream or sys.stderr
    handler = logging.StreamHandler(stream)
    handler.setFormatter(JournalFormatter() if under_journal(stream) else
                         logging.Formatter("%(asctime)s %(levelname)-7s %(name)s: %(message)s"))
    root = logging.getLogger("palpd")
    root.handlers[:] = [handler]
    root.setLevel(level.upper())
    root.propagate = False
    return root
