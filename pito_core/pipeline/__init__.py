"""The one live pipeline (no Qt): new samples → pairing → tare → calibration → face wrenches → contacts.

>>> from pito_core.pipeline import Pipeline, AcquisitionReader       # doctest: +SKIP
>>> pipe = Pipeline(calibration, "pito_mixed")
>>> reader = AcquisitionReader(acquisition)
>>> bundle = pipe.feed(reader.read())      # every tick: a LiveBundle of the new samples

The app (devices: :class:`PipelineProcess`; a replay: :class:`PipelineThread`), ``pito record``,
``pito replay`` (:class:`RecordingReader`, :func:`replay_recording`) and ``pito bench`` all call
:meth:`Pipeline.feed`/:meth:`Pipeline.process`; the pairing rule is
:mod:`pito_core.devices._clock` (docs/devices.md, "Pairing the cube and the reference").
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ..devices import PAIRING_RULE, TareCheck, TareRefused, TareSupport, check_tare
    from ._bundle import LiveBundle, face_sums
    from ._pipeline import Pipeline
    from ._open import open_acquisition, open_reader
    from ._launch import PipelineLaunch
    from ._process import PipelineProcess, PipelineProcessError
    from ._readers import (AcquisitionReader, NewSamples, RecordingReader, device_time_base, recording_samples,
                           recording_times)
    from ._replay import concatenate_bundles, replay_blocks, replay_recording
    from ._thread import PipelineThread

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "TareCheck",
    "TareRefused",
    "TareSupport",
    "check_tare",
    "AcquisitionReader",
    "LiveBundle",
    "NewSamples",
    "PAIRING_RULE",
    "Pipeline",
    "PipelineLaunch",
    "PipelineProcess",
    "PipelineProcessError",
    "PipelineThread",
    "RecordingReader",
    "face_sums",
    "open_acquisition",
    "open_reader",
    "recording_samples",
    "replay_recording",
    "replay_blocks",
    "concatenate_bundles",
    "device_time_base",
    "recording_times",
]
