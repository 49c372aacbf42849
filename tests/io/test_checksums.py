"""Every file pito writes carries checksums; a flipped bit anywhere in a dataset is refused.

The property tests flip one bit at a random byte of the stored data of a random dataset (offsets from
h5py's ``get_offset`` / ``get_chunk_info``) and require a :class:`ChecksumError` naming the file and
that dataset. Recordings: a flip at any byte of the file is refused.
"""

import functools
import tempfile
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pito_core.calibration import CalibrationSession, calibrate, load_calibration
from pito_core.io import (
    ChecksumError,
    FileFormatError,
    Recording,
    RecordingWriter,
    UnverifiedFileWarning,
    calibration_hash,
    short_hash,
    verify_file,
    write_session,
)
from pito_core.sim import random_sensor, random_sensor_session

_TMP = Path(tempfile.mkdtemp(prefix="pito-integrity-"))


def _session():
    sensor = random_sensor(5)
    s, _ = random_sensor_session(sensor, "frame_hole", 3, 40, n_tare=30, seed=1)
    return s


@functools.lru_cache(maxsize=None)
def _files():
    s = _session()
    sp = _TMP / "s.pitosession"
    write_session(sp, s)
    cal = calibrate(s, "face_to_face")
    cp = _TMP / "c.pitocal"
    cal.save(cp)
    return {"session": sp, "calibration": cp}, cal


def _regions(path):
    """[(dataset name, byte offset, length)] of every stored chunk / contiguous block."""
    out = []

    def visit(name, obj):
        if not isinstance(obj, h5py.Dataset) or obj.size == 0:
            return
        dsid = obj.id
        if obj.chunks is None:
            off = dsid.get_offset()
            if off is not None:
                out.append((obj.name, off, dsid.get_storage_size()))
        else:
            for i in range(dsid.get_num_chunks()):
                info = dsid.get_chunk_info(i)
                out.append((obj.name, info.byte_offset, info.size))

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return out


def _load(kind, path):
    if kind == "calibration":
        return load_calibration(path)
    return CalibrationSession.load(path)


@pytest.mark.parametrize("kind", ["session", "calibration"])
def test_every_dataset_is_checksummed(kind):
    files, _ = _files()
    with h5py.File(files[kind], "r") as f:
        assert "pito_checksums" in f.attrs
        names = []
        f.visititems(lambda n, o: names.append(o) if isinstance(o, h5py.Dataset) else None)
        assert names
        for ds in names:
            if ds.size:
                assert ds.fletcher32, ds.name
    assert verify_file(files[kind]) is True
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a verified file loads without a warning
        _load(kind, files[kind])


@pytest.mark.parametrize("kind", ["session", "calibration"])
@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(data=st.data())
def test_a_flipped_bit_in_any_dataset_is_refused_naming_it(kind, data):
    files, _ = _files()
    path = files[kind]
    regions = _regions(path)
    assert {r[0] for r in regions} >= ({"/matrix", "/offset", "/T_core_ati"} if kind == "calibration" else {"/counts", "/reference", "/loaded"})
    name, off, size = data.draw(st.sampled_from(regions), label="dataset region")
    pos = off + data.draw(st.integers(0, size - 1), label="byte")
    bit = data.draw(st.integers(0, 7), label="bit")
    raw = bytearray(path.read_bytes())
    raw[pos] ^= 1 << bit
    bad = _TMP / f"bad-{kind}{path.suffix}"
    bad.write_bytes(bytes(raw))
    with pytest.raises(ChecksumError) as err:
        _load(kind, bad)
    assert err.value.dataset == name and str(bad) in str(err.value) and name in str(err.value)
    with pytest.raises(ChecksumError):
        verify_file(bad)


def test_lazy_session_refuses_a_flipped_chunk_when_it_is_read():
    files, _ = _files()
    path = files["session"]
    name, off, size = next(r for r in _regions(path) if r[0] == "/counts")
    raw = bytearray(path.read_bytes())
    raw[off + size // 2] ^= 0x10
    bad = _TMP / "lazy-bad.pitosession"
    bad.write_bytes(bytes(raw))
    s = CalibrationSession.load(bad, lazy=True)  # the big datasets are checked chunk by chunk as they are read
    with pytest.raises(ChecksumError, match="/counts"):
        s.counts[0 : len(s.counts)]
    with pytest.raises(ChecksumError, match="/counts"):
        verify_file(bad)


def test_changed_attribute_or_added_dataset_is_refused():
    files, _ = _files()
    bad = _TMP / "attr.pitocal"
    bad.write_bytes(files["calibration"].read_bytes())
    with h5py.File(bad, "a") as f:
        f.attrs["core_edge"] = f.attrs["core_edge"] * (1 + 1e-15)
    with pytest.raises(ChecksumError, match="'/'"):
        load_calibration(bad)
    bad.write_bytes(files["calibration"].read_bytes())
    with h5py.File(bad, "a") as f:
        f["matrix"].attrs["note"] = "x"
    with pytest.raises(ChecksumError, match="/matrix"):
        load_calibration(bad)
    bad.write_bytes(files["calibration"].read_bytes())
    with h5py.File(bad, "a") as f:
        f["extra"] = np.zeros(3)
    with pytest.raises(ChecksumError, match="/extra"):
        load_calibration(bad)


@pytest.mark.parametrize("kind", ["session", "calibration"])
def test_old_files_without_checksums_load_with_a_warning(kind):
    files, _ = _files()
    old = _TMP / f"old-{kind}{files[kind].suffix}"
    old.write_bytes(files[kind].read_bytes())
    with h5py.File(old, "a") as f:
        del f.attrs["pito_checksums"]
    with pytest.warns(UnverifiedFileWarning, match="cannot be verified"):
        _load(kind, old)
    with pytest.warns(UnverifiedFileWarning):
        assert verify_file(old) is False


def test_calibration_hash_is_stable_and_content_sensitive():
    files, cal = _files()
    back = load_calibration(files["calibration"])
    h = calibration_hash(cal)
    assert len(h) == 64 and h == calibration_hash(back) and short_hash(h) == h[:12]
    back.matrix[0, 0] = np.nextafter(back.matrix[0, 0], np.inf)
    assert calibration_hash(back) != h


def _recording(path):
    rng = np.random.default_rng(2)
    with RecordingWriter(path, {"simulated": True, "note": "integrity test"}, flush_interval=1.0, fsync=False) as w:
        for k in range(3):
            n = 20
            w.append_pito(np.arange(n) + k * n, np.arange(n) * 1000, np.arange(n) * 1e-3 + k, rng.integers(-9, 9, (n, 36)))
            w.append_netft(np.arange(n), np.arange(n), np.zeros(n), np.arange(n) * 1e-3 + k, rng.normal(size=(n, 6)))
            w.append_event({"kind": "tare", "k": k})
            w.flush()


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(data=st.data())
def test_recording_any_flipped_bit_is_refused(data):
    path = _TMP / "r.rec"
    if not path.exists():
        _recording(path)
    raw = bytearray(path.read_bytes())
    pos = data.draw(st.integers(0, len(raw) - 1), label="byte")
    raw[pos] ^= 1 << data.draw(st.integers(0, 7), label="bit")
    bad = _TMP / "r-bad.rec"
    bad.write_bytes(bytes(raw))
    with pytest.raises(FileFormatError) as err:
        Recording(bad)
    assert str(bad) in str(err.value)
