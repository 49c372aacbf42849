"""File formats: sessions, calibrations, recordings; CSV and MATLAB export."""

from ._calibration_file import CALIBRATION_FORMAT, CALIBRATION_VERSION, read_calibration, write_calibration
from ._csv import CSV_COUNTS, CSV_LOADED, CSV_REFERENCE, read_session_csv, write_session_csv
from ._hdf5 import FileFormatError
from ._session_file import SESSION_FORMAT, SESSION_VERSION, read_session, write_session
from ._recording import (
    NETFT_ROW,
    PITO_ROW,
    RECORDING_FORMAT,
    RECORDING_VERSION,
    Recording,
    RecordingWriter,
    ReplayBatch,
    read_recording,
)
from ._export import RECORDING_CSV_COLUMNS, export_recording_csv, export_recording_mat, read_recording_csv

__all__ = [
    "CALIBRATION_FORMAT",
    "CALIBRATION_VERSION",
    "read_calibration",
    "write_calibration",
    "FileFormatError",
    "SESSION_FORMAT",
    "SESSION_VERSION",
    "read_session",
    "write_session",
    "read_session_csv",
    "write_session_csv",
    "CSV_COUNTS",
    "CSV_REFERENCE",
    "CSV_LOADED",
    "RECORDING_FORMAT",
    "RECORDING_VERSION",
    "PITO_ROW",
    "NETFT_ROW",
    "Recording",
    "RecordingWriter",
    "ReplayBatch",
    "read_recording",
    "RECORDING_CSV_COLUMNS",
    "export_recording_csv",
    "export_recording_mat",
    "read_recording_csv",
]
