"""NWB export round trip: written by `pito export --nwb`, read back with pynwb (and nwbinspector when installed)."""

import json

import numpy as np
import pytest

pynwb = pytest.importorskip("pynwb", reason="the interop extra (pip install -e '.[interop]') is not installed")

from pito_core.interop import export_data, write_nwb  # noqa: E402

from .conftest import pito  # noqa: E402


@pytest.fixture(scope="module")
def nwb_file(interop_files):
    d, _, rec, _ = interop_files
    out = d / "grasp.nwb"
    r = pito("export", rec, "--nwb", out, "--subject-id", "S01", "--species", "Homo sapiens", "--sex", "F", "--age", "P30Y",
             "--experimenter", "Doe, Jane", "--lab", "Grasp lab", "--institution", "Tactile University")
    assert "recording's own calibration" in r.stdout
    assert "warning" not in r.stderr  # all the metadata nwbinspector looks for were given
    return out, export_data(rec)


def test_nwb_round_trip(nwb_file):
    path, data = nwb_file
    with pynwb.NWBHDF5IO(str(path), "r") as io:
        f = io.read()
        assert f.subject.subject_id == "S01" and f.subject.species == "Homo sapiens"
        assert f.subject.sex == "F" and f.subject.age == "P30Y"
        assert tuple(f.experimenter) == ("Doe, Jane",) and f.lab == "Grasp lab"
        assert "SIMULATED" in f.session_description
        counts = f.acquisition["pito_raw_counts"]
        assert counts.unit == "counts" and counts.data.shape == (data.n, 36)
        np.testing.assert_array_equal(counts.data[:], data.counts)
        np.testing.assert_allclose(series_times(counts), data.time, rtol=0, atol=1e-9)
        assert np.all(np.diff(series_times(counts)) > 0)  # the cube's clock: never a repeated time
        assert f.acquisition["reference_force"].unit == "N" and f.acquisition["reference_torque"].unit == "N*m"
        rf = f.acquisition["reference_force"]
        assert rf.data.shape == (data.reference_time.size, 3) and np.isfinite(rf.data[:]).all()
        np.testing.assert_array_equal(rf.data[:], data.reference_wrench[:, :3])
        np.testing.assert_allclose(series_times(rf), data.reference_time, rtol=0, atol=1e-9)
        assert np.all(np.diff(series_times(rf)) > 0) and series_times(rf)[0] >= 0
        w = f.processing["behavior"]
        for i in range(1, 7):
            F, T = w[f"face_{i}_force"], w[f"face_{i}_torque"]
            assert F.unit == "N" and T.unit == "N*m" and f"face {i}" in F.description
            np.testing.assert_allclose(F.data[:], data.face_wrenches[:, i - 1, :3])
            np.testing.assert_allclose(T.data[:], data.face_wrenches[:, i - 1, 3:])
            np.testing.assert_allclose(series_times(F), data.time, rtol=0, atol=1e-9)
        c = f.processing["behavior"]
        valid_any = False
        for i in range(1, 7):
            pt = c[f"contact_face_{i}"]["point"]
            assert pt.reference_frame.startswith("pito_core") and pt.unit == "meters"
            np.testing.assert_array_equal(np.isnan(pt.data[:]), np.isnan(data.contacts.point[:, i - 1]))
            valid = c[f"contact_face_{i}_valid"].data[:]
            np.testing.assert_array_equal(valid, data.contacts.valid[:, i - 1])
            valid_any |= bool(valid.any())
            for key in ("single_contact", "single_contact_p", "single_contact_reason"):
                np.testing.assert_array_equal(c[f"contact_face_{i}_{key}"].data[:], getattr(data.contacts, key)[:, i - 1])
            assert "torsion" in c[f"contact_face_{i}_single_contact_reason"].description
        assert valid_any, "the simulated grasp touches at least one face"
        cm = f.processing["misc"]["calibration_matrix"].to_dataframe()
        np.testing.assert_allclose(np.stack(cm["coefficients"].to_numpy()), np.asarray(data.calibration["matrix"]))
        assert list(cm["component"][:6]) == ["fx", "fy", "fz", "tx", "ty", "tz"]
        assert data.calibration["hash"] in f.processing["misc"]["calibration_matrix"].description
        off = f.processing["misc"]["calibration_offset"].to_dataframe()
        np.testing.assert_allclose(off["offset_counts"], data.calibration["offset"])
        assert data.calibration["hash"] in f.notes and "pito_mixed" in f.notes
        cf = f.processing["misc"]["calibration_file"]
        assert "".join(cf["content_base64"][:]) == data.calibration["file"]["content"]
        assert json.loads(cf.description)["content_hash"] == data.calibration["hash"]


def test_nwb_without_calibration_has_counts_and_reference_only(interop_files, tmp_path):
    _, _, _, raw = interop_files
    data = export_data(raw)
    write_nwb(data, tmp_path / "raw.nwb")
    with pynwb.NWBHDF5IO(str(tmp_path / "raw.nwb"), "r") as io:
        f = io.read()
        assert set(f.acquisition) == {"pito_raw_counts", "pito_host_time", "reference_force", "reference_torque"}
        assert len(f.processing) == 0


def series_times(ts) -> np.ndarray:
    """A TimeSeries' sample times, s (its timestamps, or starting_time + k / rate)."""
    if ts.timestamps is not None:
        return np.asarray(ts.timestamps[:], float)
    return ts.starting_time + np.arange(ts.data.shape[0]) / ts.rate


def _inspect(path):
    pytest.importorskip("nwbinspector", reason="nwbinspector not installed")
    from nwbinspector import inspect_nwbfile

    return list(inspect_nwbfile(nwbfile_path=str(path)))


def test_nwbinspector_finds_nothing_with_the_metadata_given(nwb_file):
    """Subject, experimenter, institution given: no CRITICAL, no best-practice finding (module names included)."""
    path, _ = nwb_file
    issues = _inspect(path)
    assert not issues, "\n".join(f"{m.importance.name} {m.check_function_name} {m.object_name}: {m.message}" for m in issues)
    with pynwb.NWBHDF5IO(str(path), "r") as io:
        assert set(io.read().processing) == {"behavior", "misc"}  # the schema's module names


def test_export_without_subject_warns_and_inspector_agrees(interop_files, tmp_path):
    """No --subject-id: `pito export` says so on stderr, naming the option; nwbinspector's CRITICAL is that finding."""
    from nwbinspector import Importance  # noqa: F401 - (skipped above when missing)

    _, _, rec, _ = interop_files
    out = tmp_path / "nosubject.nwb"
    r = pito("export", rec, "--nwb", out)
    assert "warning" in r.stderr and "--subject-id" in r.stderr and "CRITICAL" in r.stderr
    critical = [m for m in _inspect(out) if m.importance.name == "CRITICAL"]
    assert [m.check_function_name for m in critical] == ["check_subject_exists"]
