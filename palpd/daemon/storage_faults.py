"""The supervisor's side of storage faults: a storage error never leaves the supervisor's loop.

A full disk drops the raw recording first (the journal keeps what room is
left); a palpation that cannot be journaled, or a failing or read-only disk,
stops the scan (category 1: the palpation under way finishes, the arm parks)
and latches a `storage` fault whose message names the cause; `reset` retries.
"""
from __future__ import annotations

import errno
import logging

from palpd.daemon import storage
from palpd.errors import PalpdError
from palpd.files import is_storage_error

log = logging.getLogger("palpd.daemon")


class StorageFaults:
    """Mixed into the Supervisor: needs its recording, samples, job, worker, session, settings, publish and
    set_state, and its _recover and _seal_recordings."""

    def recover_storage(self) -> bool:
        """Recover the unfinished session (once) and prune; False (storage_cause set) on a storage error."""
        try:
            if not self._recovered:
                self._recover()
            elif self.session is not None:  # a storage fault mid-scan cut its recording: sealed now there is room
                self._seal_recordings(self.session)
            storage.probe_writable(self.sessions_dir)
            self.prune_sessions()
        except (OSError, PalpdError) as exc:
            if not is_storage_error(exc):
                raise
            self.storage_cause = storage.cause(exc, "start-up: recovering the sessions", self.sessions_dir)
            return False
        self.storage_cause = ""
        return True

    def _record(self, action, *args) -> None:
        """A write to the recording; a storage error drops the recording (or faults) instead of raising."""
        try:
            action(*args)
        except OSError as exc:
            if not is_storage_error(exc):
                raise
            self._recording_failed(exc)

    def _recording_failed(self, exc: OSError) -> None:
        """A full disk drops the raw recording first, so the journal keeps what room is left; a failing or
        read-only disk is a storage fault at once."""
        if not isinstance(self.recording, storage.DroppedRecording):
            if self.recording is not None:
                self.recording.abandon()
            self.recording = storage.DroppedRecording(self.samples)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            log.warning("raw samples are no longer recorded, palpations are still journaled: %s",
                        storage.cause(exc, "recording", self.sessions_dir))
        else:
            self.storage_failed("recording", exc)

    def storage_failed(self, what: str, exc: BaseException) -> None:
        """A storage error is a `storage` fault: a scan under way stops (the palpation under way finishes, the
        arm parks clear of the tissue: a category-1 stop); the daemon stays up, serving status and events."""
        if self.storage_cause:
            return  # the first cause is the one to fix
        self.storage_cause = storage.cause(exc, what, self.sessions_dir)
        if self.job is not None:
            self.job.stop_reason = "storage"
            self.worker.request_stop()  # job_ended makes it the fault once the arm is parked
        else:
            self.storage_fault()

    def storage_fault(self) -> None:
        message = self.storage_cause + (f" ({self.samples.dropped} raw samples not recorded)"
                                        if self.samples.dropped else "")
        self.publish("fault", self.now(), code="storage", message=message)
        self.set_state("fault", f"storage: {self.storage_cause}")

    def prune_sessions(self) -> None:
        daemon = self.settings.daemon
        in_use = {s.name for s in (self.session, self.probe_session) if s is not None}
        storage.prune(self.sessions_dir, daemon.max_sessions_mb, daemon.keep_days, in_use)
        warning = storage.usage_warning(self.sessions_dir, daemon.max_sessions_mb)
        if warning and warning.split(":")[0] != self._storage_warning.split(":")[0]:
            log.warning("%s", warning)
        self._storage_warning = warning
