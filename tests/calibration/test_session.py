import h5py
import numpy as np
import pytest

from pito_core.calibration import CalibrationSession
from pito_core.io import FileFormatError

rng = np.random.default_rng(7)


def small(n=500, **kw):
    counts = rng.integers(-(10**7), 10**7, size=(n, 36)).astype(np.int32)
    reference = rng.normal(size=(n, 6))
    loaded = np.zeros((n, 6), bool)
    loaded[n // 5 :, 2] = True
    args = dict(T_core_ati=np.eye(4), flange="face", connected_face=6)
    args.update(kw)
    return CalibrationSession(counts, reference, loaded, time=np.arange(n) * 1e-3, meta={"operator": "A", "k": [1, 2]}, **args)


def test_validation_names_the_field():
    s = small()
    good = dict(counts=s.counts, reference=s.reference, loaded=s.loaded, T_core_ati=np.eye(4), flange="face", connected_face=1)
    cases = [
        (dict(counts=s.counts[:, :35]), r"counts: expected shape \(N, 36\), got \(500, 35\)"),
        (dict(reference=s.reference[:, :5]), r"reference: expected shape \(N, 6\)"),
        (dict(reference=s.reference[:10]), r"reference: expected 500 rows to match counts, got 10"),
        (dict(loaded=s.loaded[:, :3]), r"loaded: expected shape \(N, 6\)"),
        (dict(loaded=np.full((500, 6), 0.5)), r"loaded: expected booleans"),
        (dict(flange="bolted"), r"flange: expected one of \('frame', 'frame_hole', 'face'\), got 'bolted'"),
        (dict(connected_face=0), r"connected_face: expected a face number 1..6, got 0"),
        (dict(T_core_ati=np.ones((4, 4))), r"T_core_ati: expected last row"),
        (dict(counts=np.where(np.arange(500)[:, None] == 3, np.nan, 1.0) * np.ones((500, 36))), r"counts: NaN or inf at sample indices \[3\]"),
        (dict(reference=np.where(np.arange(500)[:, None] == 8, np.inf, 0.0) * np.ones((500, 6))), r"reference: NaN or inf at sample indices \[8\]"),
    ]
    for change, match in cases:
        args = dict(good, **change)
        with pytest.raises(ValueError, match=match):
            CalibrationSession(**args)
    with pytest.raises(ValueError, match=r"time: expected shape \(500,\)"):
        CalibrationSession(**good, time=np.arange(3))
    with pytest.raises(ValueError, match=r"counts_range: expected \(lo, hi\) with lo < hi"):
        CalibrationSession(**good, counts_range=(5, 1))


def test_save_load_round_trip_exact(tmp_path):
    s = small()
    path = tmp_path / "session.pito"  # exactly the name given, no extension added
    s.save(path)
    assert path.exists() and not (tmp_path / "session.pito.h5").exists()
    t = CalibrationSession.load(path)
    assert t.counts.dtype == np.int32
    for name in ("counts", "reference", "loaded", "T_core_ati", "time"):
        np.testing.assert_array_equal(getattr(t, name), getattr(s, name))
    assert (t.flange, t.connected_face, t.core, t.meta, t.counts_range) == (s.flange, s.connected_face, s.core, s.meta, s.counts_range)


def test_lazy_load_reads_blocks(tmp_path):
    s = small(3000)
    s.save(tmp_path / "s.h5")
    t = CalibrationSession.load(tmp_path / "s.h5", lazy=True)
    assert not isinstance(t.counts, np.ndarray)
    got = np.vstack([b.counts for b in t.iter_blocks(512)])
    np.testing.assert_array_equal(got, s.counts)


def test_csv_round_trip(tmp_path):
    s = small(200)
    s.to_csv(tmp_path / "s.csv")
    t = CalibrationSession.from_csv(tmp_path / "s.csv", flange="face", connected_face=6)
    np.testing.assert_array_equal(t.counts, s.counts)
    np.testing.assert_array_equal(t.reference, s.reference)  # repr() of floats round-trips exactly
    np.testing.assert_array_equal(t.loaded, s.loaded)
    np.testing.assert_array_equal(t.time, s.time)


def test_csv_errors(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("time,fx\n0,1\n")
    with pytest.raises(ValueError, match=r"missing columns \['counts_1'"):
        CalibrationSession.from_csv(p, flange="face", connected_face=6)
    s = small(5)
    s.to_csv(p)
    text = p.read_text().splitlines()
    text[2] = text[2].rsplit(",", 1)[0] + ",maybe"
    p.write_text("\n".join(text))
    with pytest.raises(ValueError, match=r"loaded_6: expected 0/1 or true/false, got 'maybe' on line 3"):
        CalibrationSession.from_csv(p, flange="face", connected_face=6)


def test_load_refuses_wrong_truncated_and_missing_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        CalibrationSession.load(tmp_path / "nope.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not an hdf5 file at all")
    with pytest.raises(FileFormatError, match="not a readable HDF5 file"):
        CalibrationSession.load(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "something-else"
    with pytest.raises(FileFormatError, match=r"expected a 'pito-session' file, got format 'something-else'"):
        CalibrationSession.load(other)
    future = tmp_path / "future.h5"
    small().save(future)
    with h5py.File(future, "a") as f:
        f.attrs["version"] = 99
    with pytest.raises(FileFormatError, match="version 99 is not supported"):
        CalibrationSession.load(future)
    good = tmp_path / "good.h5"
    small(20000).save(good)
    data = good.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(FileFormatError):
        CalibrationSession.load(cut)


def test_split_is_stratified_and_disjoint():
    n = 6000
    loaded = np.zeros((n, 6), bool)
    for k in range(5):
        loaded[1000 + k * 1000 : 2000 + k * 1000, k] = True
    s = CalibrationSession(np.arange(n * 36).reshape(n, 36), np.zeros((n, 6)), loaded, np.eye(4), "face", 6)
    train, test = s.split(0.2, block=100, seed=3)
    assert len(train) + len(test) == n
    assert np.intersect1d(train.counts[:, 0], test.counts[:, 0]).size == 0
    for part in (train, test):
        assert (~part.loaded.any(axis=1)).sum() > 0  # both keep a tare
        assert part.loaded.any(axis=0)[:5].all()  # every loaded face on both sides
    assert 0.15 < len(test) / n < 0.25
