"""The one ring buffer (``pito_core.devices.Ring``): every read against a plain list of all rows appended."""

import numpy as np
import pytest

from pito_core.devices import Ring

FIELDS = {"i": (np.int64, ()), "v": (np.float32, (2, 3)), "ok": (bool, ())}


def _block(start, n):
    """Rows ``start .. start + n - 1``: ``i`` the row number, ``v`` derived from it, ``ok`` its parity."""
    i = np.arange(start, start + n)
    return {"i": i, "v": (i[:, None, None] + np.arange(6).reshape(2, 3) / 10).astype(np.float32), "ok": i % 2 == 0}


def _check_rows(rows, numbers):
    numbers = np.asarray(numbers, dtype=np.int64)
    want = _block(0, 0) if numbers.size == 0 else {k: v[numbers - numbers[0]] for k, v in _block(numbers[0], numbers.size).items()}
    assert rows.keys() == FIELDS.keys()
    for k, (dt, shape) in FIELDS.items():
        assert rows[k].dtype == np.dtype(dt), k
        assert rows[k].shape == (numbers.size,) + shape, k
        assert np.array_equal(rows[k], want[k]), k


@pytest.mark.parametrize("contiguous", [False, True])
def test_reads_match_every_row_appended_across_wraps(contiguous):
    cap = 37
    ring = Ring(cap, FIELDS, contiguous=contiguous)
    rng = np.random.default_rng(11)
    total, cursor = 0, 0
    for _ in range(400):
        n = int(rng.integers(0, 2 * cap))  # blocks up to twice the capacity
        ring.append(**_block(total, n))
        total += n
        assert ring.count == total and len(ring) == min(total, cap)
        k = int(rng.integers(0, cap + 5))  # more than held: what is held
        _check_rows(ring.last(k), np.arange(max(0, total - min(k, cap)), total))
        _check_rows(ring.last(), np.arange(max(0, total - cap), total))
        if rng.random() < 0.5:  # a reader that keeps up, or falls behind
            rows, new, lost = ring.since(cursor)
            first = max(cursor, total - cap)
            assert lost == first - cursor and new == total
            _check_rows(rows, np.arange(first, total))
            cursor = new


def test_a_block_longer_than_the_capacity_keeps_its_last_rows():
    ring = Ring(5, FIELDS)
    ring.append(**_block(0, 3))
    ring.append(**_block(3, 12))  # 15 rows appended, the last 5 held
    assert ring.count == 15 and len(ring) == 5
    _check_rows(ring.last(), np.arange(10, 15))
    rows, cursor, lost = ring.since(2)
    assert (cursor, lost) == (15, 8)
    _check_rows(rows, np.arange(10, 15))


def test_empty_reads_have_the_fields_dtype_and_shape():
    ring = Ring(4, FIELDS)
    _check_rows(ring.last(), [])
    _check_rows(ring.last(3), [])
    rows, cursor, lost = ring.since(0)
    assert (cursor, lost) == (0, 0)
    _check_rows(rows, [])
    ring.append(**_block(0, 0))  # an empty block changes nothing
    assert ring.count == 0
    ring.append(**_block(0, 6))
    _check_rows(ring.last(0), [])
    _check_rows(ring.since(6)[0], [])
    ring.clear()
    assert ring.count == 0 and len(ring) == 0
    _check_rows(ring.last(), [])
    ring.append(**_block(0, 2))  # after a clear: row 0 again
    _check_rows(ring.last(), [0, 1])


def test_since_with_a_limit_returns_the_oldest_rows_first():
    ring = Ring(10, FIELDS)
    ring.append(**_block(0, 8))
    rows, cursor, lost = ring.since(2, limit=4)
    assert (cursor, lost) == (6, 0)
    _check_rows(rows, np.arange(2, 6))
    rows, cursor, _ = ring.since(cursor, limit=4)
    assert cursor == 8
    _check_rows(rows, [6, 7])


def test_copies_and_views():
    ring = Ring(4, {"x": (np.float64, ())}, contiguous=True)
    ring.append(x=np.arange(6.0))  # wrapped: rows 2..5 held
    view = ring.last(copy=False)["x"]
    copy = ring.last()["x"]
    since = ring.since(3)[0]["x"]
    assert np.array_equal(view, [2, 3, 4, 5]) and np.shares_memory(view, ring.data["x"])
    assert not np.shares_memory(copy, ring.data["x"]) and not np.shares_memory(since, ring.data["x"])
    ring.append(x=np.array([6.0, 7.0]))
    assert np.array_equal(copy, [2, 3, 4, 5]) and np.array_equal(since, [3, 4, 5])  # copies keep their rows
    assert np.array_equal(ring.last(copy=False)["x"], [4, 5, 6, 7])
    # a plain ring across the end of its storage: one array joined from two slices, still oldest first
    plain = Ring(4, {"x": (np.float64, ())})
    plain.append(x=np.arange(6.0))
    assert np.array_equal(plain.last(copy=False)["x"], [2, 3, 4, 5])


def test_values_are_cast_to_the_field_dtype():
    ring = Ring(3, {"n": (np.uint32, ()), "w": (np.float64, (6,))})
    ring.append(n=np.array([1.0, 2.0]), w=np.ones((2, 6), dtype=np.float32))
    rows = ring.last()
    assert rows["n"].dtype == np.uint32 and rows["w"].dtype == np.float64 and rows["w"].shape == (2, 6)


def test_bad_input_names_the_field():
    ring = Ring(3, {"t": (np.float64, ()), "w": (np.float64, (6,))})
    with pytest.raises(ValueError, match=r"missing \['w'\]"):
        ring.append(t=np.zeros(2))
    with pytest.raises(ValueError, match=r"unknown \['x'\]"):
        ring.append(t=np.zeros(2), w=np.zeros((2, 6)), x=np.zeros(2))
    with pytest.raises(ValueError, match=r"w: expected rows of shape \(6,\), got an array of shape \(2, 3\)"):
        ring.append(t=np.zeros(2), w=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"w: expected 2 rows like the other fields, got 3"):
        ring.append(t=np.zeros(2), w=np.zeros((3, 6)))
    with pytest.raises(ValueError, match="capacity"):
        Ring(0, {"t": (np.float64, ())})
    with pytest.raises(ValueError, match="capacity"):
        Ring(2.5, {"t": (np.float64, ())})
    with pytest.raises(ValueError, match="fields"):
        Ring(3, {})
    assert ring.count == 0  # a refused block leaves the ring as it was
