"""ATI DAQ .cal files: parsing and voltages → wrench in SI.

No published example output of the vendor's library was found (its sample program prints
values for a calibration file that is not public), so these tests use synthetic .cal files
with a known matrix; the voltages are the sample bias/reading of the vendor's ftconvert.c.
"""

import numpy as np
import pytest

from pito_core.devices import load_ati_calibration
from pito_core.devices._atical import tool_transform_matrix

# sample voltages of the vendor's ftconvert.c (6 gauges + thermistor)
SAMPLE_BIAS = [0.2651, -0.0177, -0.0384, -0.0427, -0.1891, 0.1373, -3.2423]
SAMPLE_READING = [-3.2863, 0.3875, -3.4877, 0.4043, -3.9341, 0.5474, -3.2106]

RNG = np.random.default_rng(7)
MATRIX = np.round(RNG.normal(0, 1, (6, 6)) * np.array([[2.0], [2.0], [3.0], [20.0], [20.0], [20.0]]), 5)


def _cal(path, matrix=MATRIX, force="N", torque="N-mm", dist="mm", transform=(0, 0, 0, 0, 0, 0), scale=None,
         extra="", axes=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), root="FTSensor"):
    scale = scale or [1.0] * 6
    rows = "\n".join(
        f'    <Axis Name="{n}" values="{" ".join(f"{v:.5f}" for v in matrix[i] * scale[i])}" max="{10 * (i + 1)}" '
        f'scale="{scale[i]}"/>'
        for i, n in enumerate(axes)
    )
    dx, dy, dz, rx, ry, rz = transform
    text = f"""<?xml version="1.0" encoding="utf-8"?>
<{root} Serial="FT-TEST" BodyStyle="Nano17" Family="DAQ" NumGages="6" CalFileVersion="1.0">
  <Calibration PartNumber="SI-TEST" CalDate="1/1/2026" ForceUnits="{force}" TorqueUnits="{torque}"
               DistUnits="{dist}" OutputMode="Ground Referenced Differential" OutputRange="20">
    <BasicTransform Dx="{dx}" Dy="{dy}" Dz="{dz}" Rx="{rx}" Ry="{ry}" Rz="{rz}"/>
{rows}
{extra}
  </Calibration>
</{root}>
"""
    path.write_text(text)
    return path


def test_nano17_units_to_si(tmp_path):
    cal = load_ati_calibration(_cal(tmp_path / "a.cal"))
    assert (cal.force_units, cal.torque_units, cal.body_style, cal.serial) == ("N", "N-mm", "Nano17", "FT-TEST")
    np.testing.assert_allclose(cal.matrix_file, MATRIX)
    v = np.subtract(SAMPLE_READING, SAMPLE_BIAS)[:6]
    expected = MATRIX @ v
    expected[3:] /= 1000.0  # N·mm → N·m
    np.testing.assert_allclose(cal.wrench_from_voltages(SAMPLE_READING, bias=SAMPLE_BIAS), expected, rtol=1e-12)
    np.testing.assert_allclose(cal.max_loads_si, [10, 20, 30, 0.04, 0.05, 0.06])
    assert not cal.temp_comp_available


def test_scale_attribute_and_batches(tmp_path):
    cal = load_ati_calibration(_cal(tmp_path / "b.cal", force="lbf", torque="lbf-in", scale=[2, 4, 8, 16, 1, 1]))
    np.testing.assert_allclose(cal.matrix_file, MATRIX, rtol=1e-6)
    v = np.random.default_rng(0).normal(size=(10, 7))
    w = cal.wrench_from_voltages(v)
    assert w.shape == (10, 6)
    np.testing.assert_allclose(w[:, :3], (v[:, :6] @ cal.matrix_file.T)[:, :3] * 4.4482216152605, rtol=1e-6)
    np.testing.assert_allclose(w[:, 3:], (v[:, :6] @ cal.matrix_file.T)[:, 3:] * 0.1129848290276167, rtol=1e-6)


def test_basic_transform_translation(tmp_path):
    # a tool frame 10 mm up z: t' = t - d × f
    cal0 = load_ati_calibration(_cal(tmp_path / "c0.cal"))
    cal = load_ati_calibration(_cal(tmp_path / "c.cal", transform=(0, 0, 10, 0, 0, 0)))
    w0 = cal0.wrench_from_voltages(SAMPLE_READING, SAMPLE_BIAS)
    w = cal.wrench_from_voltages(SAMPLE_READING, SAMPLE_BIAS)
    d = np.array([0, 0, 0.010])
    np.testing.assert_allclose(w[:3], w0[:3])
    np.testing.assert_allclose(w[3:], w0[3:] - np.cross(d, w0[:3]), rtol=1e-12, atol=1e-15)


def test_tool_transform_rotation_is_proper():
    T = tool_transform_matrix([0.01, -0.02, 0.03], np.deg2rad([10, 20, 30]))
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)
    Rz = tool_transform_matrix([0, 0, 0], [0, 0, np.pi / 2])[:3, :3]
    np.testing.assert_allclose(Rz @ [1, 0, 0], [0, -1, 0], atol=1e-12)  # the vendor's convention


def test_temperature_compensation_flag(tmp_path):
    extra = '<BiasSlope values="0 0 0 0 0 0"/><GainSlope values="0 0 0 0 0 0"/><Thermistor value="0"/>'
    assert load_ati_calibration(_cal(tmp_path / "t.cal", extra=extra)).temp_comp_available


def test_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_ati_calibration(tmp_path / "none.cal")
    with pytest.raises(ValueError, match="root element"):
        load_ati_calibration(_cal(tmp_path / "r.cal", root="Other"))
    with pytest.raises(ValueError, match="Axis: missing"):
        load_ati_calibration(_cal(tmp_path / "m.cal", matrix=MATRIX[:5], axes=("Fx", "Fy", "Fz", "Tx", "Ty")))
    with pytest.raises(ValueError, match="TorqueUnits"):
        load_ati_calibration(_cal(tmp_path / "u.cal", torque="foot-pound"))
    with pytest.raises(ValueError, match="index"):
        load_ati_calibration(_cal(tmp_path / "i.cal"), index=2)
    (tmp_path / "x.cal").write_text("not xml <")
    with pytest.raises(ValueError, match="not an ATI .cal file"):
        load_ati_calibration(tmp_path / "x.cal")
    cal = load_ati_calibration(_cal(tmp_path / "ok.cal"))
    with pytest.raises(ValueError, match="voltages"):
        cal.wrench_from_voltages(np.zeros(5))
    with pytest.raises(ValueError, match="bias"):
        cal.wrench_from_voltages(np.zeros(6), bias=np.zeros(3))
