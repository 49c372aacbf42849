"""A whole recording through the pipeline, as fast as possible."""

from __future__ import annotations

from ._pipeline import Pipeline
from ._readers import NewSamples, RecordingReader

__all__ = ["replay_recording"]


def replay_recording(recording, calibration=None, assembly=None, *, pipeline: Pipeline | None = None,
                     **pipeline_options):
    """Every sample of ``recording`` through the one pipeline: ``(bundle, pipeline)``.

    Parameters
    ----------
    recording : path or Recording
    calibration, assembly
        As :class:`Pipeline` (ignored when ``pipeline`` is given).
    pipeline : Pipeline, optional
        Use this one (e.g. to compute contacts at chosen samples afterwards).
    **pipeline_options
        Passed to :class:`Pipeline`.

    Returns
    -------
    bundle : LiveBundle
        All cube samples in order: ``time``, ``tick``, ``counts``, ``reference`` (paired by
        the pairing rule, tared by the recording's tare events), ``face_wrenches (n, 6, 6)``
        with a calibration; ``wrenches``/``contacts`` of the last sample.
    pipeline : Pipeline
    """
    reader = RecordingReader(recording, speed=float("inf"), loop=False)
    if pipeline is None:
        pipeline = Pipeline(calibration, assembly, has_reference=reader.has_reference, **pipeline_options)
    samples = reader.read()
    bundle = pipeline.feed(NewSamples(samples.cube, samples.reference, samples.events, restart=True), flush=True)
    bundle.stats = {"simulated": reader.simulated, "duration": reader.duration, "replay": True}
    return bundle, pipeline
