"""ATI DAQ F/T calibration files (``.cal``, XML): load, and gauge voltages → wrench in SI.

A ``.cal`` file holds, per ``<Calibration>``, the units (``ForceUnits``, ``TorqueUnits``,
``DistUnits``, optional ``AngleUnits``), one ``<Axis Name=... values=... max=... scale=...>``
per output axis (the calibration matrix row, in output units per volt, divided by
``scale``), an optional ``<BasicTransform Dx Dy Dz Rx Ry Rz>`` (a built-in tool transform)
and, for sensors with software temperature compensation, ``<BiasSlope>``, ``<GainSlope>``
and ``<Thermistor>``.

The conversion follows the vendor's documented algorithm (ATI DAQ F/T C library):
``wrench = M (v - v_bias)`` with ``M = T_tool · B`` where B is the basic matrix and
``T_tool`` the 6×6 tool transform. Here both are converted to SI first, so a Nano17 file
in N and N·mm gives N and N·m. Software temperature compensation is not applied (sensors
sold since 2003 compensate in hardware); :attr:`AtiCalibration.temp_comp_available` says
whether the file has it.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ._netft import FORCE_UNITS, TORQUE_UNITS

__all__ = ["AtiCalibration", "load_ati_calibration", "DIST_UNITS"]

#: SI value (m) of one unit of distance in a .cal file.
DIST_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254, "ft": 0.3048}
_ANGLE_UNITS = {"deg": np.pi / 180, "degree": np.pi / 180, "degrees": np.pi / 180,
                "rad": 1.0, "radian": 1.0, "radians": 1.0}
_AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


@dataclass(frozen=True)
class AtiCalibration:
    """One calibration of an ATI DAQ F/T transducer.

    Attributes
    ----------
    serial, body_style, part_number, cal_date : str
    force_units, torque_units, dist_units : str
        Units of the file (e.g. ``"N"``, ``"N-mm"``, ``"mm"`` for a Nano17).
    matrix_file : ndarray, shape (6, n_gauges)
        Basic matrix as in the file (values / scale): file force/torque units per volt.
    max_loads : ndarray, shape (6,)
        Rated loads, file units.
    basic_transform : ndarray, shape (6,)
        ``[Dx, Dy, Dz, Rx, Ry, Rz]`` in ``dist_units`` and ``angle_units``.
    angle_units : str
    temp_comp_available : bool
    matrix : ndarray, shape (6, n_gauges)
        Working matrix in SI: rows ``[fx, fy, fz, tx, ty, tz]`` in N/V and N·m/V, with the
        basic transform applied.
    """

    serial: str
    body_style: str
    part_number: str
    cal_date: str
    force_units: str
    torque_units: str
    dist_units: str
    angle_units: str
    matrix_file: np.ndarray
    max_loads: np.ndarray
    basic_transform: np.ndarray
    temp_comp_available: bool
    matrix: np.ndarray

    @property
    def n_gauges(self) -> int:
        return int(self.matrix.shape[1])

    @property
    def max_loads_si(self) -> np.ndarray:
        """Rated loads ``(6,)`` in N and N·m."""
        return self.max_loads * _unit_scale(self.force_units, self.torque_units)

    def wrench_from_voltages(self, voltages, bias=None) -> np.ndarray:
        """Wrench in SI from gauge voltages.

        Parameters
        ----------
        voltages : array-like, shape (..., n_gauges) or (..., n_gauges + 1)
            Gauge voltages in V (a trailing thermistor channel is ignored).
        bias : array-like, shape (n_gauges,) or (n_gauges + 1,), optional
            Unloaded voltages subtracted first (the library's ``Bias``).

        Returns
        -------
        ndarray, shape (..., 6)
            ``[fx, fy, fz, tx, ty, tz]`` in N and N·m, transducer frame (after the basic transform).
        """
        g = self.n_gauges
        v = np.asarray(voltages, dtype=float)
        if v.ndim == 0 or v.shape[-1] not in (g, g + 1):
            raise ValueError(f"voltages: expected shape (..., {g}) or (..., {g + 1}), got {v.shape}")
        v = v[..., :g]
        if bias is not None:
            b = np.asarray(bias, dtype=float)
            if b.shape not in ((g,), (g + 1,)):
                raise ValueError(f"bias: expected shape ({g},) or ({g + 1},), got {b.shape}")
            v = v - b[:g]
        return v @ self.matrix.T


def _unit_scale(force_units: str, torque_units: str) -> np.ndarray:
    if force_units not in FORCE_UNITS:
        raise ValueError(f"ForceUnits: unknown unit {force_units!r} (known: {sorted(FORCE_UNITS)})")
    if torque_units not in TORQUE_UNITS:
        raise ValueError(f"TorqueUnits: unknown unit {torque_units!r} (known: {sorted(TORQUE_UNITS)})")
    f, t = FORCE_UNITS[force_units], TORQUE_UNITS[torque_units]
    return np.array([f, f, f, t, t, t])


def tool_transform_matrix(d, angles) -> np.ndarray:
    """6×6 matrix moving a wrench to a tool frame displaced by ``d`` and rotated by ``angles``.

    ``f' = R f``, ``t' = R (t − d × f)`` with R built from the rotations Rx, Ry, Rz as ATI
    documents for its tool transforms (angles in rad, ``d`` in m).
    """
    sx, sy, sz = np.sin(angles)
    cx, cy, cz = np.cos(angles)
    R = np.array(
        [
            [cy * cz, sx * sy * cz + cx * sz, sx * sz - cx * sy * cz],
            [-cy * sz, -sx * sy * sz + cx * cz, sx * cz + cx * sy * sz],
            [sy, -sx * cy, cx * cy],
        ]
    )
    dx, dy, dz = d
    skew = np.array([[0.0, -dz, dy], [dz, 0.0, -dx], [-dy, dx, 0.0]])
    T = np.zeros((6, 6))
    T[:3, :3] = R
    T[3:, 3:] = R
    T[3:, :3] = -R @ skew
    return T


def _floats(text: str, n: int, what: str, path) -> np.ndarray:
    try:
        vals = np.array([float(x) for x in text.split()], dtype=float)
    except ValueError:
        raise ValueError(f"{path}: {what}: expected numbers, got {text!r}") from None
    if vals.size < n:
        raise ValueError(f"{path}: {what}: expected {n} values, got {vals.size}")
    return vals[:n]


def load_ati_calibration(path, index: int = 1) -> AtiCalibration:
    """Load calibration ``index`` (1-based, as the vendor library) from an ATI ``.cal`` file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not an ATI calibration file or a field is missing or malformed
        (the message names the field).
    """
    path = os.fspath(path)
    root, n_gauges = _sensor_element(path)
    cal, angle_units = _calibration_element(path, root, index)
    a = cal.attrib
    B, max_loads = _axis_rows(path, cal, n_gauges)
    bt = cal.find("BasicTransform")
    tt = np.zeros(6)
    if bt is not None:
        tt = np.array([float(bt.attrib.get(k, "0")) for k in ("Dx", "Dy", "Dz", "Rx", "Ry", "Rz")])
    unit = _unit_scale(a["ForceUnits"], a["TorqueUnits"])
    T = tool_transform_matrix(tt[:3] * DIST_UNITS[a["DistUnits"]], tt[3:] * _ANGLE_UNITS[angle_units])
    matrix = T @ (B * unit[:, None])
    temp = any(cal.find(tag) is not None for tag in ("BiasSlope", "GainSlope", "Thermistor"))
    return AtiCalibration(
        serial=root.attrib.get("Serial", ""),
        body_style=root.attrib.get("BodyStyle", ""),
        part_number=a.get("PartNumber", ""),
        cal_date=a.get("CalDate", ""),
        force_units=a["ForceUnits"],
        torque_units=a["TorqueUnits"],
        dist_units=a["DistUnits"],
        angle_units=angle_units,
        matrix_file=B,
        max_loads=np.array(max_loads),
        basic_transform=tt,
        temp_comp_available=temp,
        matrix=matrix,
    )


def _sensor_element(path: str):
    """The ``FTSensor`` root of the ``.cal`` file at ``path`` and its gauge count."""
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{path}: not an ATI .cal file (XML error: {exc})") from None
    if root.tag != "FTSensor":
        raise ValueError(f"{path}: not an ATI .cal file (root element {root.tag!r}, expected 'FTSensor')")
    try:
        n_gauges = int(root.attrib["NumGages"])
    except (KeyError, ValueError):
        raise ValueError(f"{path}: FTSensor/NumGages: expected an integer") from None
    return root, n_gauges


def _calibration_element(path: str, root, index: int):
    """Calibration ``index`` (1-based) of the file's root, its units checked; and its angle unit."""
    cals = root.findall("Calibration")
    if not 1 <= index <= len(cals):
        raise ValueError(f"index: expected 1..{len(cals)} for {path}, got {index!r}")
    cal = cals[index - 1]
    a = cal.attrib
    for key in ("ForceUnits", "TorqueUnits", "DistUnits"):
        if key not in a:
            raise ValueError(f"{path}: Calibration/{key}: missing")
    angle_units = a.get("AngleUnits", "degrees")
    if a["DistUnits"] not in DIST_UNITS:
        raise ValueError(f"{path}: DistUnits: unknown unit {a['DistUnits']!r}")
    if angle_units not in _ANGLE_UNITS:
        raise ValueError(f"{path}: AngleUnits: unknown unit {angle_units!r}")
    return cal, angle_units


def _axis_rows(path: str, cal, n_gauges: int):
    """The six axes' rows of the vendor matrix ``(6, n_gauges)`` (their scale divided out) and max loads."""
    axes = {ax.attrib.get("Name"): ax for ax in cal.findall("Axis")}
    missing = [n for n in _AXES if n not in axes]
    if missing:
        raise ValueError(f"{path}: Axis: missing {missing} (a 6-axis calibration is expected)")
    rows, max_loads = [], []
    for name in _AXES:
        ax = axes[name].attrib
        if "values" not in ax:
            raise ValueError(f"{path}: Axis {name}/values: missing")
        scale = float(ax.get("scale", "1"))
        rows.append(_floats(ax["values"], n_gauges, f"Axis {name}/values", path) / scale)
        max_loads.append(float(ax.get("max", "0")))
    return np.array(rows), max_loads
