"""Data fingerprints (data_fingerprint.py): the training timestamps, every intrinsic, signed zeros,
and the frozen digest of runs and SIMs saved before 2026-11-28 (`sampled`)."""

import hashlib
from types import SimpleNamespace

import numpy as np
from spikegs.data.trajectory import Trajectory
from spikegs.data_fingerprint import data_fingerprint, same_data, spikes_fingerprint
from spikegs.spikes.stream import SpikeStream


def _stream(length=40, seed=0):
    bits = np.random.default_rng(seed).random((length, 3, 10)) < 0.3
    return SpikeStream.from_bits(bits)


def _dataset(center_x=0.0, K=None, timestamps=(5, 20, 30)):
    """A stand-in of what data_fingerprint reads: two poses at readouts 0 and 39 (identity
    rotation, camera centres (center_x, 0, -5) and (center_x, 1, -5)), intrinsics K."""
    c2w = np.tile(np.eye(4), (2, 1, 1))
    c2w[:, :3, 3] = [[center_x, 0.0, -5.0], [center_x, 1.0, -5.0]]
    K = np.array([[20.0, 0, 5], [0, 20.0, 1.5], [0, 0, 1]], np.float32) if K is None else K
    return SimpleNamespace(
        train_timestamps=np.asarray(timestamps),
        streams=[_stream()],
        trajectory=Trajectory([0.0, 39.0], np.linalg.inv(c2w)),
        K=K,
    )


def test_the_training_timestamps_are_part_of_the_spikes_fingerprint():
    """A SIM trained at other timestamps of the same spikes is another SIM."""
    s = _stream()
    assert spikes_fingerprint(s, [10, 20]) != spikes_fingerprint(s, [10, 21])
    assert spikes_fingerprint(s, [10, 20], sampled=True) != spikes_fingerprint(
        s, [10, 21], sampled=True
    )


def test_every_intrinsic_is_part_of_the_data_fingerprint():
    """Not only fx: fy, cx and cy each change what training reads."""
    base = _dataset()
    prints = {data_fingerprint(base, 7.0)}
    for i, j in ((0, 0), (1, 1), (0, 2), (1, 2)):
        K = base.K.copy()
        K[i, j] += 0.5
        prints.add(data_fingerprint(_dataset(K=K), 7.0))
    assert len(prints) == 5


def test_a_pose_rounding_to_minus_zero_is_the_same_data():
    """Poses are rounded to 6 decimals so that another machine's last bits do not count: a
    centre 1e-9 either side of zero (the same data there) rounds to -0.0 on one side, whose bytes
    differ from 0.0's."""
    assert data_fingerprint(_dataset(center_x=1e-9), 7.0) == data_fingerprint(
        _dataset(center_x=-1e-9), 7.0
    )
    assert data_fingerprint(_dataset(center_x=1e-3), 7.0) != data_fingerprint(_dataset(), 7.0)


def test_the_sampled_fingerprint_of_earlier_runs_is_frozen():
    """`sampled=True` must reproduce the digest that SIMs and runs saved before 2026-11-28 hold:
    sha256 of the timestamps (int64), then per stream its [length, height, width] (int64) and
    its readouts at 16 indices spread evenly over [0, length - 1] (truncated), one-readout
    windows as uint8 [1, H, W]. Built here from that description, not from the code."""
    streams = [_stream(40, 0), _stream(40, 1)]
    timestamps = [5, 20, 30]
    want = hashlib.sha256(np.array(timestamps, np.int64).tobytes())
    for s in streams:
        want.update(np.array([40, 3, 10], np.int64).tobytes())
        for k in (np.arange(16) * 39 / 15).astype(np.int64):
            want.update(s.window(int(k), 1).astype(np.uint8).tobytes())
    assert spikes_fingerprint(streams, timestamps, sampled=True) == want.hexdigest()


def test_the_digest_of_a_stream_is_frozen():
    """SpikeStream.digest, which cached SIMs and runs' fingerprints hold: sha256 of [length,
    height, width] (int64) then every readout packed in the memory layout (rows of ceil(W/8)
    bytes, least significant bit first), built here with numpy's packbits."""
    bits = np.random.default_rng(3).random((7, 3, 10)) < 0.3
    packed = np.packbits(bits, axis=-1, bitorder="little")  # [7, 3, 2]
    want = hashlib.sha256(np.array([7, 3, 10], np.int64).tobytes() + packed.tobytes()).digest()
    assert SpikeStream.from_bits(bits).digest() == want


def test_poses_and_intrinsics_equal_to_6_decimals_are_the_same_data():
    """Interpolated poses and calibrations that differ in their 7th decimal (another machine's
    BLAS and libm) must still resume."""
    K = lambda f: np.array([[f, 0, 5], [0, f, 1.5], [0, 0, 1]])  # noqa: E731
    one = data_fingerprint(_dataset(center_x=0.1234561, K=K(20.1234561)), 7.0)
    assert one == data_fingerprint(_dataset(center_x=0.1234562, K=K(20.1234562)), 7.0)


def test_a_run_resumes_on_its_own_data_alone():
    """A saved fingerprint matches today's or the sampled one of the same data, never
    another dataset's."""
    data, other = _dataset(), _dataset(center_x=1.0)
    assert same_data(data_fingerprint(data, 7.0), data, 7.0)
    assert same_data(data_fingerprint(data, 7.0, sampled=True), data, 7.0)
    assert not same_data(data_fingerprint(other, 7.0), data, 7.0)
    assert not same_data(data_fingerprint(other, 7.0, sampled=True), data, 7.0)
