"""Fit into the lab: LSL live streams, NWB and ROS 2 MCAP files, provenance (docs/interop.md).

``pylsl``, ``pynwb`` and ``mcap``/``mcap_ros2`` (the optional extra ``pito[interop]``) are
imported only by the functions that need them.

>>> from pito_core.interop import export_data, export_files, write_nwb, write_mcap   # doctest: +SKIP
>>> data = export_data("grasp.pitorec")              # the recording's own calibration, in memory
>>> write_nwb(data, "grasp.nwb", subject_id="S01"); write_mcap(data, "grasp.mcap")
>>> export_files("hour.pitorec", nwb="hour.nwb", mcap="hour.mcap")   # streamed: any length
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._conventions import (
        CONTACT_CHANNEL_COUNT,
        CONTACT_CHANNELS,
        CONTACT_STREAM,
        CONTACT_TYPE,
        CORE_FRAME,
        ROS_CORE_FRAME,
        ROS_FACE_FRAME,
        WRENCH_CHANNELS,
        WRENCH_STREAM,
        WRENCH_TYPE,
    )
    from ._data import ExportData, ExportStream, export_data, export_files
    from ._lsl import (
        LslPublisher,
        contact_samples,
        listening_sockets,
        lsl_stream_infos,
        machine_only_config,
        wrench_samples,
    )
    from ._mcap import McapWriter, write_mcap
    from ._nwb import BEHAVIOR_MODULE, MISC_MODULE, NwbWriter, missing_metadata, write_nwb
    from ._nwb_trials import GRASP_PHASES_TABLE, append_grasp_phases
    from ._provenance import (
        BULKY_RECORD_KEYS,
        assembly_record,
        calibration_file_bytes,
        calibration_from_bytes,
        record_file_bytes,
        calibration_from_record,
        calibration_hash,
        calibration_record,
        provenance_meta,
        recording_calibration,
    )

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "BEHAVIOR_MODULE", "MISC_MODULE", "missing_metadata",
    "CONTACT_CHANNEL_COUNT",
    "CONTACT_CHANNELS",
    "CONTACT_STREAM",
    "CONTACT_TYPE",
    "CORE_FRAME",
    "ROS_CORE_FRAME",
    "ROS_FACE_FRAME",
    "WRENCH_CHANNELS",
    "WRENCH_STREAM",
    "WRENCH_TYPE",
    "ExportData",
    "ExportStream",
    "export_files",
    "McapWriter",
    "NwbWriter",
    "GRASP_PHASES_TABLE",
    "append_grasp_phases",
    "LslPublisher",
    "BULKY_RECORD_KEYS",
    "assembly_record",
    "calibration_file_bytes",
    "calibration_from_bytes",
    "record_file_bytes",
    "calibration_from_record",
    "calibration_hash",
    "calibration_record",
    "contact_samples",
    "listening_sockets",
    "export_data",
    "lsl_stream_infos",
    "machine_only_config",
    "provenance_meta",
    "recording_calibration",
    "wrench_samples",
    "write_mcap",
    "write_nwb",
]
