"""The requests a consumer makes of the one pipeline, whichever runs it (a thread or a process).

:class:`PipelineControls` names each request once — settings, tare, recording — and sends it
through the runner's ``_call(name, *args, timeout=...)``: :class:`~pito_core.pipeline.PipelineThread`
calls the :class:`~pito_core.pipeline._runner.PipelineRunner` under its lock (a change applies
between two reads); :class:`~pito_core.pipeline.PipelineProcess` sends the request to its
child and waits for the reply.
"""

from __future__ import annotations

import os

__all__ = ["PipelineControls"]


class PipelineControls:
    """Settings, tare and recording requests of the one pipeline (mixed into its runners)."""

    def _call(self, name: str, *args, timeout: float = 10.0):  # pragma: no cover - each runner has its own
        raise NotImplementedError

    # ------------------------------------------------------------------ settings of the pipeline
    def set_calibration(self, calibration) -> None:
        """:meth:`Pipeline.set_calibration`, between two reads (a child gets the calibration pickled)."""
        self._call("set_calibration", calibration)

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        """:meth:`Pipeline.set_assembly`, between two reads (a library assembly goes by name)."""
        self._call("set_assembly", assembly, wrench_cov)

    def set_sample_contacts(self, on: bool) -> None:
        """:meth:`Pipeline.set_sample_contacts`: every arrived sample's contacts in the bundles (the LSL streams)."""
        self._call("set_sample_contacts", bool(on))

    def tare(self, duration: float = 0.5, check: bool = False, support=None) -> dict:
        """:meth:`Pipeline.tare` (recorded when recording); returns the event.

        ``support`` (a :class:`~pito_core.devices.TareSupport`, pickled to a child): the object may rest
        on its base face. A refused tare (``check``) raises ``TareRefused`` (a ``ValueError``) with the reason."""
        return self._call("tare", float(duration), bool(check), support)

    def undo_tare(self) -> dict:
        """:meth:`Pipeline.undo_tare` (recorded when recording); returns the event."""
        return self._call("undo_tare")

    def apply_tare(self, event: dict) -> None:
        """:meth:`Pipeline.apply_tare`: a tare taken before this pipeline (Back to live)."""
        self._call("apply_tare", dict(event))

    def reset(self) -> None:
        """:meth:`Pipeline.reset`."""
        self._call("reset")

    # ------------------------------------------------------------------ recording
    def open_recording(self, path, meta: dict | None = None) -> None:
        """Record every sample of both devices from now on to ``path`` (``pito-recording``).

        Only a running acquisition can be recorded (a replay raises ``ValueError``)."""
        self._call("open_recording", os.fspath(path), dict(meta or {}))

    def close_recording(self) -> dict:
        """Stop recording and close the file (returns once closed): ``{"rows": {...}, "path": ...}`` or {}."""
        return self._call("close_recording", timeout=30.0)

    def record_event(self, event: dict) -> None:
        """Append ``event`` (JSON-able dict) to the recording, if recording."""
        self._call("record_event", dict(event))
