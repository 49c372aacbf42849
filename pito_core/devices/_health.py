"""Device health in words: stall transitions and the health part of a status line (CLI and app)."""

from __future__ import annotations

__all__ = ["health_words", "StallReporter"]


def health_words(stats: dict) -> list[str]:
    """Short health words for an ``Acquisition.stats()`` dict: ``["cube stalled", "ati rate mismatch", ...]``.

    Empty when both devices are healthy. ``stats`` is ``{"pito": PitoSerial.stats(), "netft": NetFT.stats() or None}``.
    """
    out = []
    p = stats.get("pito") or {}
    if p.get("stalled"):
        out.append(f"cube stalled ({p.get('since_data_s', 0.0) * 1e3:.0f} ms without a frame)")
    f = stats.get("netft")
    if f:
        if f.get("stalled"):
            out.append(f"ati stalled ({f.get('since_data_s', 0.0) * 1e3:.0f} ms without a record)")
        if f.get("rate_mismatch"):
            rate = f.get("rate_hz")
            out.append(
                f"ati rate mismatch (box configured {f.get('configured_rate_hz')} Hz, received "
                f"{'?' if rate is None else f'{rate:.0f}'} Hz, lag {f.get('lag_ms') or 0:.0f} ms)"
            )
        if f.get("last_status"):
            out.append(f"ati status 0x{int(f['last_status']):08x}")
    return out


class StallReporter:
    """Turns successive stats into lines when a device stalls or resumes (poll it every ≤ 50 ms)."""

    def __init__(self):
        self._was = {"pito": False, "netft": False}

    def changes(self, stats: dict) -> list[str]:
        lines = []
        for key, name in (("pito", "cube"), ("netft", "ati")):
            d = stats.get(key)
            if not d or "stalled" not in d:
                continue
            now = bool(d["stalled"])
            if now != self._was[key]:
                lines.append(
                    f"{name} stalled: no data for {d.get('since_data_s', 0.0) * 1e3:.0f} ms (stall {d.get('stalls', 0)})"
                    if now
                    else f"{name} resumed after {d.get('stalled_s', 0.0):.2f} s stalled in all ({d.get('stalls', 0)} stalls)"
                )
                self._was[key] = now
        return lines
