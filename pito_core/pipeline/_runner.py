"""A reader and the one pipeline, with the requests a live view makes: one implementation for both
places the live pipeline runs — the pipeline process's child (:mod:`._process_child`) and
:class:`~pito_core.pipeline.PipelineThread` (a replay in the caller's process).

:class:`PipelineRunner` holds no thread and no lock: its owner calls it from one thread at a time.
"""

from __future__ import annotations

from ._bundle import LiveBundle
from ._pipeline import Pipeline

__all__ = ["PipelineRunner", "REQUESTS"]

#: The runner's methods a caller may ask for by name (the pipeline process's protocol).
REQUESTS = ("set_calibration", "set_assembly", "set_sample_contacts", "tare", "undo_tare", "apply_tare", "reset", "open_recording",
            "close_recording", "record_event")


class PipelineRunner:
    """``reader.read()`` → :meth:`Pipeline.feed` → one :class:`LiveBundle` per :meth:`bundle`, plus the settings.

    Parameters
    ----------
    reader : AcquisitionReader or RecordingReader
        Where the new samples come from. A reader with an ``acq`` (a running acquisition) can
        record (``pito-recording``, written by the acquisition's collecting thread); a
        recording cannot.
    pipeline : Pipeline
        The one pipeline (its ``has_reference`` should be the reader's).
    """

    def __init__(self, reader, pipeline: Pipeline):
        self.reader = reader
        self.pipeline = pipeline
        self.acq = getattr(reader, "acq", None)
        self.recording_from: int | None = None  # cube cursor where the recording began

    # ------------------------------------------------------------ settings (Pipeline's)
    def set_calibration(self, calibration) -> None:
        self.pipeline.set_calibration(calibration)

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        self.pipeline.set_assembly(assembly, wrench_cov)

    def set_sample_contacts(self, on: bool) -> None:
        self.pipeline.set_sample_contacts(on)

    def tare(self, duration: float = 0.5, check: bool = False, support=None) -> dict:
        """:meth:`Pipeline.tare`; the event is recorded when recording. Refused: ``TareRefused`` (a ValueError)."""
        event = self.pipeline.tare(duration, check=bool(check), support=support)
        self.record_event(event)
        return event

    def undo_tare(self) -> dict:
        """:meth:`Pipeline.undo_tare`; the event is recorded when recording."""
        event = self.pipeline.undo_tare()
        self.record_event(event)
        return event

    def apply_tare(self, event: dict) -> None:
        self.pipeline.apply_tare(event)

    def reset(self) -> None:
        self.pipeline.reset()

    # ------------------------------------------------------------ recording
    def open_recording(self, path, meta: dict | None = None) -> None:
        """Record every sample of both devices from now on to ``path``.

        Raises
        ------
        ValueError
            The reader is not a running acquisition (a replay cannot be recorded).
        """
        if self.acq is None:
            raise ValueError("recording: the source is not a device acquisition (a replay cannot be recorded)")
        meta = dict(meta or {})
        meta.setdefault("simulated", bool(getattr(self.acq, "meta", {}).get("simulated", False)))
        self.acq.open_recording(path, meta)
        self.recording_from = self.acq.cursors()[0]

    def close_recording(self) -> dict:
        """Close the recording (returns once closed): ``{"rows": {...}, "path": ...}``, or {} when none."""
        self.recording_from = None
        return {} if self.acq is None else self.acq.close_recording()

    def record_event(self, event: dict) -> None:
        """Append ``event`` to the recording, if recording."""
        if self.acq is not None:
            self.acq.record_event(event)

    # ------------------------------------------------------------ the pipeline
    def bundle(self) -> LiveBundle:
        """The new rows through the pipeline, with the device figures, the samples recorded and the replay position."""
        b = self.pipeline.feed(self.reader.read())
        b.stats = self.reader.stats()
        b.recorded = 0 if self.recording_from is None else self.acq.cursors()[0] - self.recording_from
        if "position" in b.stats:  # a recording: s into it, and its length
            b.replay_position = b.stats["position"]
            b.replay_duration = b.stats.get("duration")
        return b

    def close(self) -> None:
        """Close the recording (if any) and the reader."""
        try:
            if self.recording_from is not None:
                self.close_recording()
        finally:
            self.reader.close()
