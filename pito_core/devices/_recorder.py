"""The recording side of an acquisition: every collected sample appended to a ``pito-recording``."""

from __future__ import annotations

from ..io import RecordingWriter

__all__ = ["Recorder"]


class Recorder:
    """Starting, stopping and writing events to the recording of :class:`~pito_core.devices.Acquisition`.

    Subclasses own ``recorder``, ``reference_rate_hz``, ``now()``, the per-stream ``_clock`` and
    ``_unwrap`` (their states start a recording), ``_lock`` and ``_collect_lock``.
    """

    def start_recording(self, writer) -> None:
        """Append every sample collected from now on to ``writer`` (a ``RecordingWriter``), beside any reader.

        Recording runs in the collecting thread, so a slow consumer (a screen) never loses
        samples. The recording's metadata gets ``reference_rate_hz`` if it has none.
        """
        with self._collect_lock:
            writer.meta.setdefault("reference_rate_hz", self.reference_rate_hz)
            with self._lock:
                # the clocks' state before the first recorded sample: the replay's times and pairing
                # are then the live ones from the first sample on (pipeline.recording_samples)
                writer.append_event({"type": "clock", "host_time": self.now(),
                                     **{name: {"clock": self._clock[name].state(), "ticks": self._unwrap[name].state()}
                                        for name in ("pito", "netft")}})
                self.recorder = writer

    def stop_recording(self):
        """Stop appending to the recorder and return it (not closed), or None."""
        with self._collect_lock:
            with self._lock:
                rec, self.recorder = self.recorder, None
        if rec is not None:
            rec.flush()
        return rec

    def open_recording(self, path, meta: dict | None = None) -> None:
        """Record every sample from now on to a new ``pito-recording`` file at ``path`` (see :meth:`start_recording`).

        The same call on :class:`~pito_core.devices.RemoteAcquisition` opens the file in the
        acquisition's own process.
        """
        self.start_recording(RecordingWriter(path, meta=dict(meta or {})))

    def record_event(self, event: dict) -> None:
        """Append ``event`` (a JSON-able dict, e.g. a pipeline's ``tare``) to the recording, if recording."""
        with self._collect_lock:
            if self.recorder is not None:
                self.recorder.append_event(event)

    def close_recording(self) -> dict:
        """Stop recording and close the file: ``{"rows": {"pito": n, "netft": m}, "path": str}`` (empty if none)."""
        rec = self.stop_recording()
        if rec is None:
            return {}
        rec.close()
        return {"rows": dict(rec.rows_written), "path": str(rec.path)}
