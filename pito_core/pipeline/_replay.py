"""A whole recording through the pipeline, as fast as possible, one block of samples at a time."""

from __future__ import annotations

import numpy as np

from ._bundle import LiveBundle
from ._pipeline import Pipeline
from ._readers import NewSamples, RecordingReader

__all__ = ["replay_recording", "replay_blocks"]

#: Seconds of cube samples per block (the pipeline's reference history holds several).
BLOCK_S = 1.0
#: Seconds of reference rows handed over beyond a block's last cube sample (its pairing partner).
LOOKAHEAD_S = 0.25


def replay_blocks(reader: RecordingReader, pipeline: Pipeline, block: float = BLOCK_S):
    """Yield the :class:`LiveBundle` of each ``block`` s of cube samples of ``reader``'s recording, in order.

    Every cube sample is in exactly one bundle (the last block is flushed); each block is fed
    with the reference rows up to :data:`LOOKAHEAD_S` s past its last cube sample and with the
    recording's tare events at their sample, so the pairing and tares are the live ones and the
    reference history the pipeline keeps (a few seconds) always covers the block.
    """
    if not block > 0:
        raise ValueError(f"block: expected > 0 s, got {block!r}")
    cube, ref = reader.cube, reader.reference
    t, tick = cube["time"], cube["tick"]
    n = t.size
    i = j = 0
    first = True
    while i < n:
        i1 = max(i + 1, int(np.searchsorted(t, t[i] + block, side="left")))
        last = i1 >= n
        if reader.has_reference:
            j1 = ref["time"].size if last else max(j, int(np.searchsorted(ref["time"], t[i1 - 1] + LOOKAHEAD_S,
                                                                          side="right")))
            r = {k: v[j:j1] for k, v in ref.items()}
        else:
            j1, r = j, None
        lo = int(tick[i - 1]) if i > 0 else -np.inf
        hi = np.inf if last else int(tick[i1 - 1])
        events = [e for e in reader.events if lo < int(e["from_tick"]) <= hi]
        yield pipeline.feed(NewSamples({k: v[i:i1] for k, v in cube.items()}, r, events, restart=first), flush=last)
        i, j, first = i1, j1, False


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
    bundle = concatenate_bundles(list(replay_blocks(reader, pipeline)))
    bundle.stats = {"simulated": reader.simulated, "duration": reader.duration, "replay": True}
    return bundle, pipeline


def concatenate_bundles(parts: list) -> LiveBundle:
    """One bundle of the records of ``parts`` (in order); the derived values (wrenches, contacts) of the last."""
    if not parts:
        raise ValueError("parts: expected at least one bundle")

    def cat(name):
        vals = [getattr(b, name) for b in parts if len(b)]
        if not vals:
            return getattr(parts[-1], name)
        return None if any(v is None for v in vals) else np.concatenate(vals)

    last = parts[-1]
    out = LiveBundle(cat("time"), cat("counts"), cat("reference"), tick=cat("tick"), face_wrenches=cat("face_wrenches"))
    src = next((b for b in reversed(parts) if b.wrenches is not None), last)
    out.wrenches, out.contacts, out.contacts_time = src.wrenches, src.contacts, src.contacts_time
    out.sum_force, out.sum_torque, out.measured = src.sum_force, src.sum_torque, src.measured
    return out
