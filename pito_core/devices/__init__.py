"""Devices: the cube's serial frames, the ATI Net F/T, ATI .cal files, acquisition and its ring buffer.

The simulated devices live in :mod:`pito_core.sim` (they speak these formats over a pty and
loopback UDP); ``devices`` never imports ``sim``.
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._acquisition import Acquisition
    from ._tare import TareCheck, TareRefused, TareSupport, check_tare, resting_load, tare_event
    from ._clock import PAIRING_RULE, StreamClock, TickUnwrapper, pair_reference
    from ._atical import DIST_UNITS, AtiCalibration, load_ati_calibration
    from ._capture import Capture, CaptureRules, FaceCaptures, is_still, on_face, scaled
    from ._frame import (
        FRAME_DTYPE,
        FRAME_SIZE,
        FRAME_SYNC,
        DecodedFrames,
        FrameDecoder,
        crc16_ccitt_false,
        crc16_ccitt_false_rows,
        pack_frames,
        unpack_frames,
    )
    from ._health import StallReporter, health_words
    from ._lifetime import die_with_parent, install_stop_signals, process_alive
    from ._netft import (
        CMD_BIAS,
        CMD_START_BUFFERED,
        CMD_START_REALTIME,
        CMD_STOP,
        FORCE_UNITS,
        RDT_HEADER,
        RDT_PORT,
        RDT_RECORD_DTYPE,
        STATUS_ERROR,
        STATUS_SATURATION,
        TORQUE_UNITS,
        NetFT,
        NetFTBatch,
        NetFTConfig,
        decode_status,
        read_netft_config,
    )
    from ._open import SIM, open_devices, parse_ati_address
    from ._ring import Ring
    from ._serial import DEFAULT_BAUDRATE, DeviceError, PitoBatch, PitoSerial, list_serial_ports

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "Capture",
    "CaptureRules",
    "FaceCaptures",
    "is_still",
    "on_face",
    "scaled",
    "TareCheck",
    "TareRefused",
    "TareSupport",
    "resting_load",
    "check_tare",
    "tare_event",
    "Acquisition",
    "Ring",
    "SIM",
    "open_devices",
    "parse_ati_address",
    "PAIRING_RULE",
    "StreamClock",
    "TickUnwrapper",
    "pair_reference",
    "AtiCalibration",
    "load_ati_calibration",
    "DIST_UNITS",
    "FRAME_DTYPE",
    "FRAME_SIZE",
    "FRAME_SYNC",
    "DecodedFrames",
    "FrameDecoder",
    "crc16_ccitt_false",
    "crc16_ccitt_false_rows",
    "pack_frames",
    "unpack_frames",
    "CMD_BIAS",
    "CMD_START_BUFFERED",
    "CMD_START_REALTIME",
    "CMD_STOP",
    "FORCE_UNITS",
    "RDT_HEADER",
    "TORQUE_UNITS",
    "RDT_PORT",
    "RDT_RECORD_DTYPE",
    "STATUS_ERROR",
    "STATUS_SATURATION",
    "NetFT",
    "NetFTBatch",
    "NetFTConfig",
    "decode_status",
    "read_netft_config",
    "DEFAULT_BAUDRATE",
    "DeviceError",
    "PitoBatch",
    "PitoSerial",
    "list_serial_ports",
    "StallReporter",
    "health_words",
    "die_with_parent",
    "install_stop_signals",
    "process_alive",
]
