"""File formats: sessions, calibrations, recordings; CSV and MATLAB export."""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._calibration_file import CALIBRATION_FORMAT, CALIBRATION_VERSION, read_calibration_fields, write_calibration
    from ._csv import CSV_COUNTS, CSV_LOADED, CSV_REFERENCE, read_session_csv_fields, write_session_csv
    from ._hdf5 import ChecksumError, FileFormatError, UnverifiedFileWarning
    from ._calhash import calibration_hash, short_hash
    from ._session_file import SESSION_FORMAT, SESSION_VERSION, read_session_fields, write_session
    from ._session import DEFAULT_COUNTS_RANGE, FLANGES, CalibrationSession, SessionBlock, few_indices
    from ._session_build import saturated_samples, session_from_arrays
    from ._recording import (
        NETFT_ROW,
        PITO_ROW,
        RECORDING_FORMAT,
        RECORDING_VERSION,
        Recording,
        RecordingChunks,
        RecordingWriter,
        ReplayBatch,
        read_recording,
    )
    from ._verify import verify_file
    from ._export import RECORDING_CSV_COLUMNS, export_recording_csv, export_recording_files, export_recording_mat, read_recording_csv

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "saturated_samples",
    "session_from_arrays",
    "CalibrationSession",
    "DEFAULT_COUNTS_RANGE",
    "FLANGES",
    "SessionBlock",
    "few_indices",
    "CALIBRATION_FORMAT",
    "CALIBRATION_VERSION",
    "read_calibration_fields",
    "write_calibration",
    "FileFormatError",
    "ChecksumError",
    "UnverifiedFileWarning",
    "verify_file",
    "calibration_hash",
    "short_hash",
    "SESSION_FORMAT",
    "SESSION_VERSION",
    "read_session_fields",
    "write_session",
    "read_session_csv_fields",
    "write_session_csv",
    "CSV_COUNTS",
    "CSV_REFERENCE",
    "CSV_LOADED",
    "RECORDING_FORMAT",
    "RECORDING_VERSION",
    "PITO_ROW",
    "NETFT_ROW",
    "Recording",
    "RecordingChunks",
    "RecordingWriter",
    "ReplayBatch",
    "read_recording",
    "RECORDING_CSV_COLUMNS",
    "export_recording_csv",
    "export_recording_files",
    "export_recording_mat",
    "read_recording_csv",
]
