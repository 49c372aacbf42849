"""The calibration's content hash: the one identity shown wherever a calibration is named."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from ._hdf5 import json_attr

__all__ = ["calibration_hash", "short_hash"]


def _arr(h, name: str, a) -> None:
    a = np.ascontiguousarray(np.asarray(a, dtype="<f8"))
    h.update(f"{name}{a.shape}".encode() + a.tobytes())


def calibration_hash(cal) -> str:
    """SHA-256 (64 hex characters) of what makes a calibration's wrenches.

    Covers the matrix (N, N·m per count), offset (counts), ``T_core_ati``, method, output frame,
    output faces, core edge (m) and the metadata (JSON, sorted keys), all as little-endian
    float64 / UTF-8 — so the same calibration has the same hash whether it was just fitted, saved
    or loaded, on any machine; with the polynomial model, its correction too. The covariance (uncertainty only) is not part of it.
    Show :func:`short_hash` of it in titles and CLI lines.
    """
    h = hashlib.sha256(b"pito-calibration-content/1\0")
    _arr(h, "matrix", cal.matrix)
    _arr(h, "offset", cal.offset)
    _arr(h, "T_core_ati", cal.T_core_ati)
    h.update(f"method={cal.method}\0frame={cal.output_frame}\0".encode())
    h.update(("faces=" + ",".join(str(int(v)) for v in cal.output_faces) + "\0").encode())
    _arr(h, "core_edge", [float(cal.core.edge)])
    corr = getattr(cal, "correction", None)
    if corr is not None:  # the polynomial model (linear calibrations keep the hash they always had)
        for name in ("scale", "pairs", "cubes", "coef", "lower", "upper", "edge_matrix", "domain",
                     "domain_lower", "domain_upper", "input_map", "tangent", "map_matrix",
                     "map_lower", "map_upper", "edge_mapped", "reach"):
            if getattr(corr, name, None) is not None:  # the range: files written before it hash as they did
                _arr(h, f"correction.{name}", getattr(corr, name))
    meta = json.loads(json_attr(cal.meta or {}))
    h.update(json.dumps(meta, sort_keys=True, allow_nan=True).encode())
    return h.hexdigest()


def short_hash(digest: str, n: int = 12) -> str:
    """The first ``n`` hex characters of a hash (for titles and one-line CLI outputs)."""
    return str(digest)[:n]
