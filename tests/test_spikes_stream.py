"""SpikeStream, save_dat and the TFP/TFI kernels against plain numpy versions."""

from __future__ import annotations

import copy
import errno
import gc
import os
import pickle
import subprocess
import sys
import tracemalloc
import warnings

import numpy as np
import pytest
from spikegs import _C, SpikeStream, save_dat
from spikegs.spikes import TFI_DEFAULT_MAX_INTERVAL, DatWriter


def random_bits(shape, p=0.3, seed=0) -> np.ndarray:
    return (np.random.default_rng(seed).random(shape) < p).astype(np.uint8)  # [T, H, W]


def numpy_read_dat(path, height, width, flip=True) -> np.ndarray:
    """The common Python reader of this family: bits over the whole frame, LSB first, flipud."""
    raw = np.fromfile(path, dtype=np.uint8)
    bits = np.unpackbits(raw, bitorder="little").reshape(-1, height * width + (-height * width) % 8)
    frames = bits[:, : height * width].reshape(-1, height, width)
    return frames[:, ::-1] if flip else frames


def naive_tfi(bits: np.ndarray, k: int, max_interval: int) -> np.ndarray:
    """TFI by its definition, one pixel at a time: 1 / min(t_next - t_prev, max_interval)."""
    out = np.empty(bits.shape[1:], np.float32)
    for idx in np.ndindex(*bits.shape[1:]):
        train = bits[(slice(None), *idx)]
        before = np.flatnonzero(train[: k + 1])
        after = np.flatnonzero(train[k + 1 :])
        interval = after[0] + k + 1 - before[-1] if before.size and after.size else max_interval
        out[idx] = 1.0 / min(interval, max_interval)
    return out


@pytest.mark.parametrize("height, width", [(6, 1), (6, 7), (6, 8), (6, 13), (6, 400), (1, 13)])
@pytest.mark.parametrize("flip", [True, False])
def test_round_trip(tmp_path, height, width, flip):
    """Every layout, one-row frames too (a row flipped wrong only there went unseen)."""
    bits = random_bits((9, height, width), seed=width)
    path = save_dat(tmp_path / "s.dat", bits, flip=flip)
    assert path.stat().st_size == 9 * -(-height * width // 8)
    s = SpikeStream.open(path, height, width, flip=flip)
    assert (len(s), s.height, s.width) == (9, height, width)
    np.testing.assert_array_equal(s.window(4, 9), bits)
    np.testing.assert_array_equal(numpy_read_dat(path, height, width, flip), bits)
    packed = s.packed()  # [T, H, ceil(W/8)]
    np.testing.assert_array_equal(packed, np.packbits(bits, axis=-1, bitorder="little"))
    np.testing.assert_array_equal(SpikeStream.from_packed(packed, height, width).window(4, 9), bits)


def test_digest_covers_every_readout_whatever_the_layout(tmp_path, monkeypatch):
    """digest() changes with any one bit of any readout (a fingerprint of 16 sampled readouts
    kept a SIM trained on spikes edited between them) and not with the file layout holding
    them (flipped or not, extra raw columns), nor with its chunk size (3 readouts here)."""
    bits = random_bits((11, 5, 13))
    digest = SpikeStream.from_bits(bits).digest()
    for flip in (True, False):
        path = save_dat(tmp_path / f"s{flip}.dat", bits, flip=flip)  # other bytes on disk
        assert SpikeStream.open(path, 5, 13, flip=flip).digest() == digest
    raw = np.pad(bits, ((0, 0), (0, 0), (2, 1)), constant_values=1)  # raw rows of 16
    crop = SpikeStream.open(save_dat(tmp_path / "raw.dat", raw), 5, 13, raw_width=16, col_offset=2)
    assert crop.digest() == digest
    monkeypatch.setattr("spikegs.spikes.stream._DIGEST_CHUNK_BYTES", 3 * 5 * 2)
    assert SpikeStream.from_bits(bits).digest() == digest
    for t, y, x in [(0, 0, 0), (5, 2, 12), (10, 4, 7)]:
        edited = bits.copy()
        edited[t, y, x] ^= 1
        assert SpikeStream.from_bits(edited).digest() != digest, (t, y, x)
    assert SpikeStream.from_bits(bits[:10]).digest() != digest


def test_a_files_digest_is_read_once_while_the_file_is_unchanged(tmp_path, monkeypatch):
    """A command asks for the digest two or three times (SIM's cache, the run's fingerprint):
    the file is read once; edited in place (its mtime moved), it is read again."""
    bits = random_bits((6, 4, 16))
    path = save_dat(tmp_path / "s.dat", bits)
    stream = SpikeStream.open(path, 4, 16)
    first = stream.digest()
    reads = []
    monkeypatch.setattr(SpikeStream, "packed", lambda self, *a: reads.append(a) or 1 / 0)
    assert stream.digest() == first and not reads
    monkeypatch.undo()
    edited = bits.copy()
    edited[0] ^= 1
    with open(path, "r+b") as f:  # in place: the same inode, the map sees the new bytes
        f.write(save_dat(tmp_path / "e.dat", edited).read_bytes())
    os.utime(path, ns=(0, path.stat().st_mtime_ns + 10**9))
    assert stream.digest() == SpikeStream.from_bits(edited).digest() != first


def test_a_long_digest_is_said_as_what_it_is(tmp_path, monkeypatch, capsys):
    """A digest of over SAID_OVER bytes (a GiB, ~1 s; here 0) is said on stderr: a file's as
    read from its path, spikes in memory's as hashed (they said "None: reading ... for its
    digest" as a flicker search keyed by them); one under it is not said."""
    bits = random_bits((6, 4, 16))
    path = save_dat(tmp_path / "s.dat", bits)
    SpikeStream.open(path, 4, 16).digest()
    SpikeStream.from_bits(bits).digest()
    assert capsys.readouterr().err == ""
    monkeypatch.setattr("spikegs.spikes.stream.SAID_OVER", 0)
    SpikeStream.open(path, 4, 16).digest()
    assert capsys.readouterr().err == f"{path}: reading 0.0 GB for its digest\n"
    SpikeStream.from_bits(bits).digest()
    said = "spikes in memory (6 readouts of 4x16): hashing 0.0 GB for their digest\n"
    assert capsys.readouterr().err == said


def test_a_large_files_digest_is_cached_for_the_next_command(tmp_path, monkeypatch):
    """Over CACHED_FROM (here 0) a file's digest is kept in $XDG_CACHE_HOME/spikegs for
    another process's stream of the same file, layout, size, mtime and inode; the file read
    another way (flipped or not) or touched is read again, and a garbled cache entry too."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr("spikegs.spikes.stream.CACHED_FROM", 0)
    bits = random_bits((6, 4, 16))
    path = save_dat(tmp_path / "s.dat", bits)
    digest = SpikeStream.open(path, 4, 16).digest()
    (entry,) = (tmp_path / "cache" / "spikegs" / "digests").iterdir()
    assert entry.read_text() == digest.hex()
    real_packed = SpikeStream.packed
    reads = []
    monkeypatch.setattr(
        SpikeStream, "packed", lambda self, *a: reads.append(a) or real_packed(self, *a)
    )
    assert SpikeStream.open(path, 4, 16).digest() == digest and not reads  # a new process's
    unflipped = SpikeStream.open(path, 4, 16, flip=False)
    assert unflipped.digest() != digest and reads  # other rows read: another key
    reads.clear()
    entry.write_text("garbled")
    assert SpikeStream.open(path, 4, 16).digest() == digest and reads
    reads.clear()
    os.utime(path, ns=(0, path.stat().st_mtime_ns + 10**9))
    assert SpikeStream.open(path, 4, 16).digest() == digest and reads


def test_a_digest_cache_that_cannot_be_written_leaves_the_digest_as_it_is(tmp_path, monkeypatch):
    """A read-only home, a full disk or a file where the cache folder goes: the digest is the
    file's all the same, nothing cached (the next command reads the file again), no error."""
    monkeypatch.setattr("spikegs.spikes.stream.CACHED_FROM", 0)
    bits = random_bits((6, 4, 16))
    path = save_dat(tmp_path / "s.dat", bits)
    (tmp_path / "cache").write_text("a file, not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert SpikeStream.open(path, 4, 16).digest() == SpikeStream.from_bits(bits).digest()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home"))

    def disk_full(path, text):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr("spikegs.cache_home.write_text_atomically", disk_full)
    assert SpikeStream.open(path, 4, 16).digest() == SpikeStream.from_bits(bits).digest()
    assert not [p for p in (tmp_path / "home").rglob("*") if p.is_file()]


def test_a_file_changed_after_open_never_caches_the_mapped_spikes_for_it(tmp_path, monkeypatch):
    """The cache holds a digest for a file only while it is the one mapped at open: grown in
    place (a recording still written) or replaced after open, the stream's digest (of what it
    mapped) is not cached for the new file, which the next process reads afresh; a file removed
    after open, or opened by a relative path before a chdir, still gives the mapped spikes'."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr("spikegs.spikes.stream.CACHED_FROM", 0)
    bits = random_bits((10, 4, 16))
    first = SpikeStream.from_bits(bits[:6]).digest()
    for change in ("grow", "replace"):
        path = save_dat(tmp_path / f"{change}.dat", bits[:6])
        stream = SpikeStream.open(path, 4, 16)
        if change == "grow":
            with open(path, "ab") as f:
                f.write(save_dat(tmp_path / "tail.dat", bits[6:]).read_bytes())
        else:
            os.replace(save_dat(tmp_path / "new.dat", bits), path)
        assert stream.digest() == first  # what it mapped
        assert SpikeStream.open(path, 4, 16).digest() == SpikeStream.from_bits(bits).digest()
    path = save_dat(tmp_path / "gone.dat", bits[:6])
    stream = SpikeStream.open(path, 4, 16)
    path.unlink()
    assert stream.digest() == first
    monkeypatch.chdir(tmp_path)
    stream = SpikeStream.open("grow.dat", 4, 16)  # 10 readouts
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    save_dat(tmp_path / "elsewhere" / "grow.dat", bits[:6])  # the same name, other spikes
    assert stream.digest() == SpikeStream.from_bits(bits).digest()
    assert SpikeStream.open("grow.dat", 4, 16).digest() == first


def test_unflipped_file_read_flipped(tmp_path):
    bits = random_bits((3, 4, 16))
    path = save_dat(tmp_path / "s.dat", bits, flip=False)
    np.testing.assert_array_equal(SpikeStream.open(path, 4, 16).window(1, 3), bits[:, ::-1])


def test_raw_width_crop(tmp_path):
    raw = random_bits((5, 4, 416))  # a camera row of 416 pixels, 400 of them image
    path = save_dat(tmp_path / "raw.dat", raw)
    s = SpikeStream.open(path, 4, 400, raw_width=416, col_offset=8)
    np.testing.assert_array_equal(s.window(2, 5), raw[:, :, 8:408])
    np.testing.assert_array_equal(s.counts(2, 5), raw[:, :, 8:408].sum(0))


@pytest.mark.parametrize("w", [1, 4, 33, 300])
def test_counts_and_tfp_match_numpy(w):
    bits = random_bits((400, 7, 37), seed=w)
    s = SpikeStream.from_bits(bits)
    ks = np.array([w // 2, 150, 400 - w + w // 2])
    want = np.stack([bits[k - w // 2 : k - w // 2 + w].sum(0) for k in ks])  # [B, H, W]
    np.testing.assert_array_equal(s.counts(ks, w), want)
    assert s.counts(ks, w).dtype == np.int32
    np.testing.assert_allclose(s.tfp(ks, w), want / w, rtol=1e-6)
    np.testing.assert_allclose(s.tfp(int(ks[1]), w), want[1] / w, rtol=1e-6)
    assert s.window(ks, w).shape == (3, w, 7, 37)


def test_kernels_read_the_packed_file_in_place(tmp_path):
    """Counts, TFP and TFI of a memory-mapped .dat allocate their output and nothing else in numpy
    (tracemalloc traces numpy's memory, not the core's): the stream reaches the core without a
    copy (2 MB here) and no window is unpacked to bytes on the way (33 bytes a pixel)."""
    height, width, slack = 64, 128, 16 << 10  # Python's own objects: a few kB
    path = save_dat(tmp_path / "s.dat", random_bits((2000, height, width), p=0.1))
    s = SpikeStream.open(path, height, width)
    ks = np.array([16, 1000, 1983])
    reads = (lambda: s.counts(ks, 33), lambda: s.tfp(ks, 33), lambda: s.tfi(ks))
    for read in reads:
        read()  # the first call's imports and caches
        tracemalloc.start()
        try:
            out = read()
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert out.nbytes <= peak <= out.nbytes + slack, (peak, out.nbytes)


def test_the_kernels_release_the_gil(longest_pause):
    """The core runs without the GIL (in per_index, which counts, TFP and TFI go through): Python's
    other threads run meanwhile. TFI over 20,000 readouts without a spike, ~0.2 s."""
    s = SpikeStream.from_packed(np.zeros((20000, 64, 16), np.uint8), 64, 128)
    assert longest_pause(lambda: s.tfi(np.arange(5000, 15000, 250), 2**30)) < 0.5


def test_all_zero_and_all_one_windows():
    for value in (0, 1):
        s = SpikeStream.from_packed(np.full((600, 3, 2), 255 * value, np.uint8), 3, 13)
        np.testing.assert_array_equal(s.tfp(25, 33), np.full((3, 13), value, np.float32))
        np.testing.assert_array_equal(s.counts(25, 50), np.full((3, 13), 50 * value))
        # past the kernel's blocks of 255 readouts (its 8-bit counters): counts and rate exact
        np.testing.assert_array_equal(s.counts(300, 600), np.full((3, 13), 600 * value))
        np.testing.assert_array_equal(s.tfp(300, 511), np.full((3, 13), value, np.float32))
        np.testing.assert_array_equal(s.tfi(10), np.full((3, 13), 1.0 if value else 1 / 1024))


def test_tfi_matches_definition():
    bits = random_bits((200, 4, 19), p=0.05, seed=3)
    s = SpikeStream.from_bits(bits)
    ks = [0, 1, 57, 198, 199]
    got = s.tfi(ks, max_interval=40)
    for i, k in enumerate(ks):
        np.testing.assert_array_equal(got[i], naive_tfi(bits, k, 40), err_msg=f"k={k}")
    assert np.isfinite(got).all() and (got > 0).all() and (got <= 1).all()


def test_tfi_edge_cases():
    train = np.zeros((12, 1, 1), np.uint8)
    train[[0, 5], 0, 0] = 1
    s = SpikeStream.from_bits(train)
    assert s.tfi(0)[0, 0] == pytest.approx(1 / 5)  # the spike at readout 0 is t_prev
    assert s.tfi(4)[0, 0] == pytest.approx(1 / 5)
    assert s.tfi(5)[0, 0] == pytest.approx(1 / TFI_DEFAULT_MAX_INTERVAL)  # nothing after 5
    assert s.tfi(11, max_interval=8)[0, 0] == pytest.approx(1 / 8)  # last readout
    assert s.tfi(2, max_interval=3)[0, 0] == pytest.approx(1 / 3)  # interval 5 capped


def test_truncated_file_refused(tmp_path):
    path = save_dat(tmp_path / "s.dat", random_bits((4, 8, 16)))
    with open(path, "ab") as f:
        f.write(b"\0" * 5)
    with pytest.raises(
        ValueError, match=r"16 bytes expected, found 69 bytes \(4 frames and 5 bytes over: is t"
    ):
        SpikeStream.open(path, 8, 16)  # 4 frames: rather a wrong size than a cut (not advised)
    path = save_dat(tmp_path / "my recording.dat", random_bits((20, 8, 16)))
    with open(path, "ab") as f:
        f.write(b"\0" * 5)
    with pytest.raises(
        ValueError,
        match=rf"5 bytes over: is the frame size, height, width or raw_width, right\?; a record"
        rf".* keeps its 20 whole frames truncated to 320 bytes \(on a copy: `truncate -s 320 "
        rf"'{path}'` deletes the rest\)\)",
    ):
        SpikeStream.open(path, 8, 16)
    with pytest.raises(ValueError, match=r"packed data: .*\(0 frames and 5 bytes over: is th"):
        SpikeStream(np.zeros(5, np.uint8), _C.SpikeLayout.memory(8, 16))  # no file to cut
    with pytest.raises(ValueError, match="expected"):
        SpikeStream.open(path, 8, 16, raw_width=12)  # raw rows narrower than the image


def test_a_folder_is_not_opened_as_a_stream(tmp_path):
    """A folder's size read as a cut-off recording's: the message said to truncate it."""
    with pytest.raises(IsADirectoryError, match="a folder, not a spike .dat file"):
        SpikeStream.open(tmp_path, 4, 20)


def test_empty_file(tmp_path):
    path = tmp_path / "empty.dat"
    path.write_bytes(b"")
    empty = SpikeStream.open(path, 4, 8)
    assert len(empty) == 0 and empty.packed().shape == (0, 4, 1)


def test_windows_past_either_end_refused():
    s = SpikeStream.from_packed(np.zeros((20, 2, 1), np.uint8), 2, 8)
    for k in (3, 16, [5, 30]):  # windows of 9 start at k - 4: k in [4, 15]
        with pytest.raises(ValueError, match=r"expected within the stream's \[0, 20\)"):
            s.counts(k, 9)
    assert s.tfp(4, 9).shape == (2, 8) and s.tfp(15, 9).shape == (2, 8)
    for k in (-1, 20):
        with pytest.raises(ValueError, match=r"expected in \[0, 20\)"):
            s.tfi(k)
    with pytest.raises(ValueError, match="window length"):
        s.tfp(5, 0)
    with pytest.raises(ValueError, match=r"window length expected an int in 1\.\.2147483647"):
        s.counts(5, 2**31)  # int32 counts: a stream that long read TFP -1 (15 h at 40 kHz)
    with pytest.raises(ValueError, match="longer than the stream's 20 readouts"):  # "k in [10, 9]"
        s.tfp(5, 21)
    # the bounds themselves are valid: the int32 limit is a window length (too long for this
    # stream), 2**30 a max_interval (both refused as out of range with < for <=)
    with pytest.raises(ValueError, match="longer than the stream's 20 readouts"):
        s.counts(5, 2**31 - 1)
    assert (s.tfi(5, 2**30) == np.float32(2.0**-30)).all()  # no spikes: 1 / max_interval
    for w in (float("inf"), float("nan"), None, True, np.array([3])):  # array: "found [3]"
        with pytest.raises(ValueError, match="window length"):
            s.tfp(5, w)
        with pytest.raises(ValueError, match="max_interval"):
            s.tfi(5, w)
    np.testing.assert_array_equal(s.tfp(5, 3.0), s.tfp(5, 3))
    for interval in (2.5, 0, 2**30 + 1, 2**63, 1e300):  # 2.5 was read as 2; 2**63: a TypeError
        with pytest.raises(ValueError, match="max_interval"):
            s.tfi(5, interval)
    for start, stop in ((1.5, None), ("1", None), (0, 2.5), (True, None)):  # TypeErrors
        with pytest.raises(ValueError, match="(start|stop): expected an int"):
            s.packed(start, stop)
    np.testing.assert_array_equal(s.packed(1.0, 3.0), s.packed(1, 3))  # as windows take them
    for k in (5.5, float("nan"), [5.0, 6.5], float("inf"), -1e30, [5.0, 2.0**64], [5, True]):
        with pytest.raises(ValueError, match="integer"):  # huge floats: not cast to garbage ints
            s.tfp(k, 3)
    np.testing.assert_array_equal(s.tfp(5.0, 3), s.tfp(5, 3))  # a readout time, e.g. a view's
    with warnings.catch_warnings():  # float16 cannot hold the bound (numpy warned of overflow)
        warnings.simplefilter("error")
        np.testing.assert_array_equal(s.tfp(np.float16([5]), 3), s.tfp([5], 3))
    big = np.iinfo(np.int64)
    for k in (big.max, big.max - 1, big.min):  # k + w would overflow: refused, no crash
        for read in (s.window, s.counts, s.tfp):
            with pytest.raises(ValueError, match=r"expected within the stream's \[0, 20\)"):
                read(k, 3)
    with pytest.raises(ValueError, match="below 2\\^63, found 9223372036854775811"):
        s.tfp(np.uint64(2**63 + 3), 3)  # was reported as k=-9223372036854775805


def test_core_refuses_windows_whose_end_overflows():
    s = SpikeStream.from_packed(np.zeros((20, 2, 1), np.uint8), 2, 8)
    data, layout = s.packed().reshape(-1), _C.SpikeLayout.memory(2, 8)
    starts = np.array([np.iinfo(np.int64).max - 1], np.int64)
    for kernel in (_C.spike_counts, _C.spike_tfp):
        with pytest.raises(ValueError, match="expected within the stream's"):
            kernel(data, layout, starts, 3)
    with pytest.raises(ValueError, match="expected within the stream's"):
        _C.spike_unpack(data, layout, int(starts[0]), 3)


def test_core_kernels_refuse_float_indices():
    """The core's index arrays take integers only (arrays or lists; int32, uint16 converted);
    float readouts were truncated (0.7 read readout 0) and booleans read as 0/1 for a direct `_C`
    caller."""
    s = SpikeStream.from_packed(np.zeros((20, 2, 1), np.uint8), 2, 8)
    data, layout = s.packed().reshape(-1), _C.SpikeLayout.memory(2, 8)
    for kernel in (_C.spike_counts, _C.spike_tfp, _C.spike_tfi):
        for bad in (np.array([0.7]), [0.7], [5.7], [True], np.array([True])):
            with pytest.raises(TypeError, match="expected integers, found dtype"):
                kernel(data, layout, bad, 3)
        for good in (np.array([2], np.int32), np.array([2], np.uint16), [2]):
            assert kernel(data, layout, good, 3).shape == (1, 2, 8)
        # uint64 past int64 was cast to a negative readout, which the error then named
        with pytest.raises(ValueError, match="below 2\\^63, found 18446744073709551615"):
            kernel(data, layout, np.array([2**64 - 1], np.uint64), 3)


def test_core_index_arrays_that_cannot_be_converted_raise_the_conversions_error():
    """Index arrays are copied to int64 (or checked as uint64): a copy that fails (numpy's size
    limit, memory) returned a null array that the binding read, a segmentation fault."""
    s = SpikeStream.from_packed(np.zeros((20, 2, 1), np.uint8), 2, 8)
    data, layout = s.packed().reshape(-1), _C.SpikeLayout.memory(2, 8)
    too_big = np.lib.stride_tricks.as_strided(np.zeros(1, np.int32), shape=(2**60,), strides=(0,))
    too_many = np.lib.stride_tricks.as_strided(np.zeros(1, np.uint64), (2**59,), strides=(0,))
    for kernel in (_C.spike_counts, _C.spike_tfp, _C.spike_tfi):
        with pytest.raises(ValueError, match="array is too big"):
            kernel(data, layout, too_big, 3)
        with pytest.raises(MemoryError):
            kernel(data, layout, too_many, 3)


def test_core_kernels_check_indices_before_allocating_their_output():
    """A batch of bad indices too large to allocate the output for (2^20 of 1024x1024 frames: 4
    TiB) raised MemoryError; the indices are checked first and named."""
    s = SpikeStream.from_packed(np.zeros((20, 1024, 128), np.uint8), 1024, 1024)
    data, layout = s.packed().reshape(-1), _C.SpikeLayout.memory(1024, 1024)
    bad = np.full(2**20, 50, np.int64)
    for kernel in (_C.spike_counts, _C.spike_tfp):
        with pytest.raises(ValueError, match=r"3 readouts from 50 expected within .*\[0, 20\)"):
            kernel(data, layout, bad, 3)
    with pytest.raises(ValueError, match=r"TFI readout expected in \[0, 20\), found 50"):
        _C.spike_tfi(data, layout, bad)


def test_core_refuses_index_and_bit_arrays_of_other_shapes():
    """A direct `_C` caller's indices must be 1-D (the kernels read as many as the first axis
    holds) and its bits [T, H, W] of the layout's H and W (the packing reads H·W a readout): other
    shapes are refused and named, not read in part or past their end."""
    s = SpikeStream.from_packed(np.zeros((20, 2, 1), np.uint8), 2, 8)
    data, layout = s.packed().reshape(-1), _C.SpikeLayout.memory(2, 8)
    for kernel in (_C.spike_counts, _C.spike_tfp, _C.spike_tfi):
        name = "readouts" if kernel is _C.spike_tfi else "starts"
        with pytest.raises(ValueError, match=rf"{name} expected 1-D, found shape \[1, 1\]"):
            kernel(data, layout, np.array([[2]]), 3)
    for bits in (np.zeros((3, 2, 7), np.uint8), np.zeros((3, 3, 8), np.uint8), np.zeros((2, 8))):
        shape = ", ".join(map(str, bits.shape))
        with pytest.raises(ValueError, match=rf"bits expected \[T, 2, 8\], found \[{shape}\]"):
            _C.spike_pack(bits, layout)
    assert _C.spike_pack(np.ones((3, 2, 8), np.uint8), layout).tolist() == [[255, 255]] * 3


def test_layouts_whose_sizes_overflow_are_refused(tmp_path):
    """col_offset + width and height * row_bits wrapped around int64: uninitialised TFPs, a
    segfault in window(), a division by zero in DatWriter."""
    from spikegs.spikes import DatWriter

    save_dat(tmp_path / "x.dat", np.zeros((3, 1, 8), np.uint8))
    with pytest.raises(ValueError, match="col_offset 9223372036854775807"):
        SpikeStream.open(tmp_path / "x.dat", 1, 1, col_offset=2**63 - 1)
    with pytest.raises(ValueError, match="below 2\\^63 bits"):
        SpikeStream.open(tmp_path / "x.dat", 2**61 + 1, 1, raw_width=8)
    with pytest.raises(ValueError, match="below 2\\^63 bits"):
        DatWriter(tmp_path / "y.dat", 2**61, 1)


def test_dat_writer_refuses_what_it_would_write_wrong(tmp_path):
    """write_bits wrote 256 as 0 and 0.5 as 0; write_packed wrote a [1, 1, 8] array for an 8x8
    camera scrambled."""
    from spikegs.spikes import DatWriter

    with DatWriter(tmp_path / "x.dat", 8, 8) as writer:
        for bad in (np.full((1, 8, 8), 256), np.full((1, 8, 8), 0.5)):
            with pytest.raises(ValueError, match="bits expected"):
                writer.write_bits(bad)
        with pytest.raises(ValueError, match=r"uint8 \[n, 8, 1\], found uint8 \[1, 1, 8\]"):
            writer.write_packed(np.zeros((1, 1, 8), np.uint8))
        writer.write_bits(np.ones((2, 8, 8), np.int64))
    assert SpikeStream.open(tmp_path / "x.dat", 8, 8).tfp(1, 1).min() == 1


def test_save_dat_of_a_stream_says_it_takes_an_array(tmp_path):
    """A SpikeStream given to save_dat was told "bits expected [T, H, W], found shape []"."""
    from spikegs.spikes import save_dat

    stream = SpikeStream.from_bits(np.ones((3, 2, 2), np.uint8))
    with pytest.raises(ValueError, match=r"bits expected an array \[T, H, W\], found a Spik"):
        save_dat(tmp_path / "x.dat", stream)
    with pytest.raises(ValueError, match=r"bits expected \[T, H, W\], found shape \[2, 2\]"):
        save_dat(tmp_path / "x.dat", np.ones((2, 2), np.uint8))
    assert not (tmp_path / "x.dat").exists()


def test_dat_writer_replaces_the_file_when_done(tmp_path, monkeypatch):
    """A stream open on a .dat keeps reading it while a new one is written to the same path (the
    file was truncated in place: its reader read zeros, or died of SIGBUS past the last page, so
    the check runs in a subprocess); a failed write leaves the earlier file and no partial one."""
    script = f"""
import numpy as np
from spikegs.spikes import SpikeStream, save_dat, simulate_spikes
path = {str(tmp_path / "x.dat")!r}
save_dat(path, np.ones((64, 8, 8), np.uint8))
old = SpikeStream.open(path, 8, 8)
new = simulate_spikes(np.zeros((1, 8, 8), np.float32), 3, out=path)
print(len(old), float(old.tfp(32, 64).mean()), len(new), len(SpikeStream.open(path, 8, 8)))
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["64", "1.0", "3", "3"]

    from spikegs.spikes import DatWriter

    path = tmp_path / "x.dat"
    with pytest.raises(ValueError, match="bits expected"):
        with DatWriter(path, 8, 8) as writer:
            writer.write_bits(np.zeros((5, 8, 8), np.uint8))
            writer.write_bits(np.full((1, 8, 8), 2))
    assert len(SpikeStream.open(path, 8, 8)) == 3
    writer = DatWriter(tmp_path / "y.dat", 8, 8)
    writer.write_bits(np.zeros((2, 8, 8), bool))
    writer.discard()
    writer.discard()  # again: nothing left to remove, no error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.dat"]
    with pytest.raises(IsADirectoryError, match="a folder"):
        DatWriter(tmp_path, 8, 8)
    with pytest.raises(FileNotFoundError) as missing:  # named its hidden temporary file
        save_dat(tmp_path / "nodir" / "x.dat", np.zeros((2, 8, 8), bool))
    assert missing.value.filename == str(tmp_path / "nodir" / "x.dat")
    with monkeypatch.context() as patch:  # it left its open partial file behind
        patch.setattr("shutil.copymode", lambda *a: exec("raise PermissionError('denied')"))
        with pytest.raises(PermissionError, match="denied"):
            DatWriter(path, 8, 8)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.dat"]
    (tmp_path / "closed").mkdir()  # closed inside its `with`: the exit's close does nothing more
    with DatWriter(tmp_path / "closed" / "z.dat", 8, 8) as writer:
        writer.write_bits(np.ones((4, 8, 8), bool))
        writer.close()
    assert len(SpikeStream.open(tmp_path / "closed" / "z.dat", 8, 8)) == 4


@pytest.mark.skipif(sys.platform == "win32", reason="symlinks, file modes and RLIMIT_FSIZE")
def test_dat_writer_keeps_links_and_modes_and_cleans_up_a_full_disk(tmp_path):
    """Written through a symlink, the target gets the readouts and the link stays (renaming
    onto the link replaced it); an existing file keeps its permissions; a disk that fills up
    mid-write leaves no hidden partial file (discard's close failed again before deleting it)."""
    real, link = tmp_path / "real.dat", tmp_path / "link.dat"
    save_dat(real, np.ones((4, 8, 8), np.uint8))
    real.chmod(0o640)
    link.symlink_to(real)
    save_dat(link, np.zeros((2, 8, 8), np.uint8))
    assert len(SpikeStream.open(real, 8, 8)) == 2 and link.is_symlink()
    assert real.stat().st_mode & 0o777 == 0o640
    script = f"""
import resource, signal, numpy as np
from spikegs.spikes import save_dat
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
try:
    save_dat({str(tmp_path / "full" / "x.dat")!r}, np.ones((400, 64, 64), np.uint8), chunk=1)
except OSError as error:
    print(error.errno)
"""
    (tmp_path / "full").mkdir()
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["27"]  # EFBIG, the write's own error
    assert list((tmp_path / "full").iterdir()) == []


def test_bad_shapes_refused(tmp_path):
    strided = np.zeros((3, 4, 4), np.uint8)[:, :, ::2]  # was "expected C-contiguous uint8,
    with pytest.raises(ValueError, match="found uint8, not C-contiguous"):  # found uint8"
        SpikeStream(strided, _C.SpikeLayout.memory(4, 16))
    with pytest.raises(ValueError, match=r"expected \[T, 4, 2\]"):
        SpikeStream.from_packed(np.zeros((3, 4, 1), np.uint8), 4, 13)
    for packed in (np.zeros((3, 4), np.uint8), np.zeros((3, 4, 2), np.int8)):  # 2-D; signed
        with pytest.raises(ValueError, match=r"packed expected uint8 \[T, H, ceil\(W/8\)\]"):
            SpikeStream.from_packed(packed, 4, 13)
    stream = SpikeStream.from_packed(np.zeros((3, 4, 2), np.uint8), 4, 13)
    for start, stop in ((2, 1), (-1, 2), (0, 4)):  # reversed, before the first, past the last
        with pytest.raises(ValueError, match=rf"readouts \[{start}, {stop}\) expected within"):
            stream.packed(start, stop)
    with pytest.raises(ValueError, match="0/1"):
        save_dat(tmp_path / "x.dat", np.full((2, 2, 8), 2, np.uint8))
    with pytest.raises(ValueError, match=r"\[T, H, W\]"):
        save_dat(tmp_path / "x.dat", np.zeros((2, 8), np.uint8))
    with pytest.raises(ValueError, match="chunk"):
        save_dat(tmp_path / "x.dat", np.zeros((2, 2, 8), np.uint8), chunk=0)
    path = tmp_path / "sizes.dat"
    save_dat(path, np.zeros((3, 4, 16), np.uint8))
    assert len(SpikeStream.open(path, np.int64(4), 16)) == 3  # numpy integers are sizes
    for sizes, message in (
        ((4.0, 16), "height: expected an int, found 4.0"),
        ((4, "16"), "width: expected an int, found '16'"),
        ((True, 16), "height: expected an int, found True"),
    ):
        with pytest.raises(ValueError, match=message):
            SpikeStream.open(path, *sizes)
    with pytest.raises(ValueError, match="flip: expected True or False, found 'false'"):
        SpikeStream.open(path, 4, 16, flip="false")  # a string in a hand-written meta.json
    with pytest.raises(ValueError, match="raw_width: expected an int, found 16.5"):
        SpikeStream.open(path, 4, 16, raw_width=16.5)
    with pytest.raises(ValueError, match="raw_width expected a positive int or None, found 0"):
        SpikeStream.open(path, 4, 16, raw_width=0)  # the core's sentinel for "= width"
    # past int64 (a spikegs.json's raw_width of 1e30 written as digits): pybind11's TypeError
    for huge in (10**30, 2**63):
        with pytest.raises(
            ValueError, match=rf"sizes.dat: raw_width: expected an int within .*{huge}"
        ):
            SpikeStream.open(path, 4, 16, raw_width=huge)
    with pytest.raises(ValueError, match="width: expected an int, found 13.0"):
        SpikeStream.from_packed(np.zeros((3, 4, 2), np.uint8), 4, 13.0)


def test_from_bits_packs_a_stream_in_memory():
    """from_bits(bits [T, H, W]) reads back its bits, for any width (a partial last byte), and
    refuses what is not 0/1 bits in three dimensions."""
    bits = random_bits((40, 3, 13), seed=5)
    s = SpikeStream.from_bits(bits.astype(bool))
    assert (len(s), s.height, s.width) == (40, 3, 13)
    np.testing.assert_array_equal(s.window(20, 40), bits)
    np.testing.assert_array_equal(s.packed(), np.packbits(bits, axis=-1, bitorder="little"))
    with pytest.raises(ValueError, match=r"bits expected 0/1, found values in \[0, 2\]"):
        SpikeStream.from_bits(bits * 2)
    with pytest.raises(ValueError, match="bits expected bool or 0/1 integers, found float64"):
        SpikeStream.from_bits(bits.astype(float))
    with pytest.raises(ValueError, match=r"bits expected \[T, H, W\], found shape \[3, 13\]"):
        SpikeStream.from_bits(bits[0])


def test_from_packed_needs_the_width():
    """A packed row of 2 bytes holds 9 to 16 columns: from_packed without width refuses to guess
    (a guess of 16 gave a 13-wide frame 3 columns that never fire), takes height from the array,
    and with width=16 keeps the last column (a default one short once dropped it)."""
    bits = np.zeros((3, 2, 16), np.uint8)
    bits[:, :, -1] = 1  # the last column fires every readout
    packed = np.packbits(bits, axis=-1, bitorder="little")
    with pytest.raises(ValueError, match="needs width=: rows of 2 bytes hold 9 to 16 columns"):
        SpikeStream.from_packed(packed)
    s = SpikeStream.from_packed(packed, width=16)
    assert (s.height, s.width) == (2, 16)
    np.testing.assert_array_equal(s.window(1, 3), bits)


@pytest.mark.parametrize("dtype", [np.int8, np.int64])
def test_negative_bits_are_refused(tmp_path, dtype):
    bits = np.zeros((2, 2, 8), dtype)
    bits[1, 0, 3] = -1
    with pytest.raises(ValueError, match=r"bits expected 0/1, found values in \[-1, 0\]"):
        SpikeStream.from_bits(bits)
    with DatWriter(tmp_path / "s.dat", 2, 8) as writer:
        with pytest.raises(ValueError, match="bits expected 0/1"):
            writer.write_bits(bits)


def test_a_stream_says_where_it_lies_and_its_size(tmp_path):
    """repr: the file a stream reads, or memory, and its readouts and frame size."""
    bits = np.zeros((3, 4, 8), bool)
    assert repr(SpikeStream.from_bits(bits)) == (
        "SpikeStream(memory, readouts=3, height=4, width=8)"
    )
    path = save_dat(tmp_path / "s.dat", bits)
    assert repr(SpikeStream.open(path, 4, 8)) == (
        f"SpikeStream('{path}', readouts=3, height=4, width=8)"
    )


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
@pytest.mark.parametrize("end", ["close", "discard"])
def test_readouts_a_full_disk_refuses_at_the_close_leave_no_file(tmp_path, end):
    """A few readouts are held in the file's buffer until it closes, where a full disk refuses
    them: `close` raises ENOSPC naming the .dat asked for, `discard` (a failure already being
    reported) says nothing more; neither leaves the .dat nor its temporary."""
    dat = tmp_path / "s.dat"
    writer = DatWriter(dat, 8, 8)
    writer._file.close()
    writer._file = open("/dev/full", "wb")  # noqa: SIM115 (the writer closes it)
    writer.write_bits(np.zeros((2, 8, 8), bool))  # 16 bytes: buffered, not yet refused
    if end == "close":
        with pytest.raises(OSError) as raised:
            writer.close()
        assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(dat)
    else:
        writer.discard()
    assert list(tmp_path.iterdir()) == []


def test_a_stream_pickles_its_file_by_path_and_its_memory_by_bytes(tmp_path):
    """A SpikeStream could not be pickled (its SpikeLayout), so no stream or dataset reached a
    spawned worker or copy.deepcopy; a file's stream now travels as its path (not its memory
    map's bytes), opened again only while it is the file it was, cropped and flipped alike."""
    bits = np.random.default_rng(0).random((2000, 5, 11)) < 0.3
    memory = SpikeStream.from_bits(bits)
    again = pickle.loads(pickle.dumps(memory))
    assert again.digest() == memory.digest() and again.path is None
    raw = np.zeros((2000, 5, 16), bool)
    raw[..., 3:14] = bits
    path = save_dat(tmp_path / "s.dat", raw, flip=False)
    opened = SpikeStream.open(path, 5, 11, flip=False, raw_width=16, col_offset=3)
    pickled = pickle.dumps(opened)
    assert len(pickled) < raw.size / 8  # (the path, not the file's bytes)
    for copy_of in (pickle.loads(pickled), copy.deepcopy(opened)):
        assert copy_of.digest() == memory.digest() and copy_of.path == path.resolve()
    os.utime(path, ns=(1, 1))  # (another file now, for all it can tell)
    with pytest.raises(ValueError, match="s.dat: changed since a SpikeStream opened it"):
        pickle.loads(pickled)


def test_a_writer_dropped_unclosed_leaves_no_hidden_file(tmp_path):
    """A DatWriter never closed left its hidden .tmp beside the file for good, unsaid."""
    writer = DatWriter(tmp_path / "a.dat", 2, 3)
    writer.write_bits(np.ones((4, 2, 3), bool))
    with pytest.warns(ResourceWarning, match="a.dat: dropped without close"):
        del writer
        gc.collect()
    assert list(tmp_path.iterdir()) == []


def test_a_window_or_interval_given_as_a_0d_tensor_or_array_is_taken():
    """`tfp(torch.tensor(3), 5)` was taken and `tfp(3, torch.tensor(5))` refused: a window,
    a TFI interval and packed's bounds take a 0-d tensor or array as their readouts do."""
    import torch

    stream = SpikeStream.from_bits(np.random.default_rng(1).random((40, 3, 5)) < 0.4)
    np.testing.assert_array_equal(stream.tfp(20, torch.tensor(5)), stream.tfp(20, 5))
    np.testing.assert_array_equal(stream.tfi(20, np.array(8)), stream.tfi(20, 8))
    np.testing.assert_array_equal(stream.packed(np.int64(2), torch.tensor(6)), stream.packed(2, 6))
    with pytest.raises(ValueError, match="window length expected an int"):
        stream.tfp(20, torch.tensor(True))
