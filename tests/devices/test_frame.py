"""The serial frame: CRC, packing, and the resynchronising decoder (no I/O)."""

import numpy as np
import pytest

from pito_core.devices import (
    FRAME_SIZE,
    FrameDecoder,
    crc16_ccitt_false,
    crc16_ccitt_false_rows,
    pack_frames,
    unpack_frames,
)


def _bitwise_crc(data: bytes) -> int:
    """Reference CRC-16/CCITT-FALSE, bit by bit, straight from the definition."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def test_crc_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1  # the catalogue check value
    assert _bitwise_crc(b"123456789") == 0x29B1


def test_crc_rows_match_reference():
    rng = np.random.default_rng(0)
    for m in (1, 2, 17, 152):
        rows = rng.integers(0, 256, (40, m), dtype=np.uint8)
        fast = crc16_ccitt_false_rows(rows)
        assert [int(c) for c in fast] == [_bitwise_crc(r.tobytes()) for r in rows]


def test_worked_example_of_docs():
    # docs/devices.md: seq 1, time 1000 µs, counts 0..35
    raw = pack_frames([1], [1000], np.arange(36)[None, :])
    assert len(raw) == FRAME_SIZE
    assert raw[:10].hex() == "aa5501000000e8030000"
    assert int.from_bytes(raw[-2:], "little") == _bitwise_crc(raw[2:154]) == 0x498D


def test_pack_unpack_round_trip():
    rng = np.random.default_rng(1)
    n = 500
    seq = rng.integers(0, 2**32, n)
    t = rng.integers(0, 2**32, n)
    counts = rng.integers(-(2**31), 2**31, (n, 36))
    f = unpack_frames(pack_frames(seq, t, counts))
    assert np.array_equal(f.seq, seq) and np.array_equal(f.time_us, t) and np.array_equal(f.counts, counts)


def test_pack_validates():
    with pytest.raises(ValueError, match="counts: expected shape"):
        pack_frames([0], [0], np.zeros((1, 35)))
    with pytest.raises(ValueError, match="seq: expected shape"):
        pack_frames([0, 1], [0], np.zeros((1, 36)))
    with pytest.raises(ValueError, match="counts: expected values in the int32 range"):
        pack_frames([0], [0], np.full((1, 36), 2**31))


def test_unpack_rejects_bad_frames():
    raw = bytearray(pack_frames([0, 1], [0, 1], np.zeros((2, 36))))
    with pytest.raises(ValueError, match="multiple of 156"):
        unpack_frames(bytes(raw[:-1]))
    bad = bytearray(raw)
    bad[156 + 40] ^= 1
    with pytest.raises(ValueError, match="frame 1 has a bad CRC"):
        unpack_frames(bytes(bad))
    bad = bytearray(raw)
    bad[0] = 0
    with pytest.raises(ValueError, match="frame 0 has bad sync"):
        unpack_frames(bytes(bad))


def test_every_single_byte_corruption_is_rejected():
    counts = np.arange(108).reshape(3, 36) * 1000
    frames = pack_frames([6, 7, 8], [6000, 7000, 8000], counts)
    for k in range(2, FRAME_SIZE):
        for flip in (0x01, 0x80, 0xFF):
            bad = bytearray(frames)
            bad[FRAME_SIZE + k] ^= flip  # frame 7 corrupt between two intact ones
            d = FrameDecoder()
            out = d.feed(bytes(bad))
            assert out.seq.tolist() == [6, 8]
            assert d.crc_errors == 1
            assert d.resyncs == 0


def _faulty_stream(seed, n=3000):
    rng = np.random.default_rng(seed)
    counts = rng.integers(-(2**31), 2**31, (n, 36))
    frames = [pack_frames([s], [s * 1000], counts[s : s + 1]) for s in range(n)]
    stream, intact = bytearray(), []
    corrupted = 0
    for s in range(n):
        r = rng.random()
        fr = bytearray(frames[s])
        if r < 0.05:
            continue  # dropped
        if r < 0.10:
            fr[rng.integers(2, FRAME_SIZE)] ^= int(rng.integers(1, 256))
            corrupted += 1
        elif r < 0.13:
            fr = fr[: rng.integers(1, FRAME_SIZE - 1)]  # truncated
        else:
            intact.append(s)
        if rng.random() < 0.05:  # line noise, sometimes a fake sync
            g = bytearray(rng.integers(0, 256, rng.integers(1, 30), dtype=np.uint8).tobytes())
            if rng.random() < 0.5:
                g[:2] = b"\xaa\x55"
            stream += g
        stream += fr
    return bytes(stream), intact, counts, corrupted


@pytest.mark.parametrize("seed", range(6))
def test_decoder_delivers_every_intact_frame_once_in_order(seed):
    stream, intact, counts, corrupted = _faulty_stream(seed)
    rng = np.random.default_rng(100 + seed)
    d = FrameDecoder()
    got_seq, got_counts = [], []
    i = 0
    while i < len(stream):
        k = int(rng.integers(1, 700))
        f = d.feed(stream[i : i + k])
        got_seq += f.seq.tolist()
        got_counts.append(f.counts)
        i += k
    assert got_seq == intact
    assert np.array_equal(np.concatenate(got_counts), counts[intact])  # no corrupt content accepted
    st = d.stats()
    assert st["frames"] == len(intact)
    assert st["crc_errors"] >= corrupted
    assert st["bytes_skipped"] == len(stream) - FRAME_SIZE * len(intact)


def test_decoder_independent_of_chunking():
    stream, intact, _, _ = _faulty_stream(42, n=800)
    results = []
    for size in (1, 155, 156, 157, 4096, len(stream)):
        d = FrameDecoder()
        seqs = []
        for i in range(0, len(stream), size):
            seqs += d.feed(stream[i : i + size]).seq.tolist()
        results.append((seqs, d.crc_errors, d.resyncs))
    assert all(r == results[0] for r in results)
    assert results[0][0] == intact


def test_resync_counted_after_garbage_not_at_start():
    f = pack_frames(np.arange(4), np.arange(4), np.zeros((4, 36)))
    d = FrameDecoder()
    out = d.feed(b"\x01\x02\x03" + f[:312] + b"\x00\xaa\x55\x09" + f[312:])
    assert out.seq.tolist() == [0, 1, 2, 3]
    assert d.resyncs == 1 and d.crc_errors == 0
    d.reset_alignment()
    out = d.feed(b"\x07" + f)
    assert out.seq.tolist() == [0, 1, 2, 3] and d.resyncs == 1
