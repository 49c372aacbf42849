"""Reading the session files named on a command line (shared by `pito calibrate` and `pito evaluate`)."""

from __future__ import annotations

from ..calibration import CalibrationSession


def load_sessions(paths, flange=None, connected_face=None):
    """Sessions from .h5 files, or .csv files with the mount given."""
    out = []
    for path in paths:
        if str(path).lower().endswith(".csv"):
            if flange is None or connected_face is None:
                raise ValueError(f"{path}: CSV sessions need --flange and --connected-face")
            out.append(CalibrationSession.from_csv(path, flange=flange, connected_face=connected_face))
        else:
            out.append(CalibrationSession.load(path))
    return out
