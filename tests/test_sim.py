"""SIM: exact blind spot, size, shapes, self-supervised training, save/load, inference, metrics."""

from __future__ import annotations

import contextlib
import errno
import filecmp
import functools
import hashlib
import json
import os
import shutil
import signal
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from skimage import data
from skimage.metrics import structural_similarity
from spikegs import sim_train
from spikegs.data_fingerprint import spikes_fingerprint
from spikegs.file_lock import exclusive_lock
from spikegs.interrupt import Terminated, raise_terminated
from spikegs.metrics import psnr, ssim, ssim_3dgs
from spikegs.output_paths import writable_folder
from spikegs.sim import SIM
from spikegs.sim_cli import _is_scores_record
from spikegs.sim_scores import compare_methods
from spikegs.sim_train import (
    bf16_is_fast,
    fast_inference_model,
    infer_sim,
    inference_model,
    load_sim,
    predict,
    recorded_seconds,
    save_sim,
    train_or_load,
    train_sim,
    user_cache,
)
from spikegs.spikes import SpikeStream
from spikegs.spikes.stream import centred_range


def valid_timestamps(stream, window: int) -> np.ndarray:
    """[M] every readout whose `window` fits in `stream`."""
    lo, hi = centred_range(len(stream), window)
    return np.arange(lo, hi + 1)


class BernoulliStream:
    """Stand-in spike stream: Bernoulli spikes, uint8 [T, H, W], with the interface SIM uses."""

    def __init__(self, rates, length: int, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.spikes = np.stack([rng.random(rates(k).shape) < rates(k) for k in range(length)])
        self.spikes = self.spikes.astype(np.uint8)  # [T, H, W]
        self.height, self.width = self.spikes.shape[1:]

    def __len__(self) -> int:
        return len(self.spikes)

    def digest(self) -> bytes:
        return hashlib.sha256(self.spikes.tobytes()).digest()

    def _each(self, k, fn) -> np.ndarray:
        return np.stack([fn(int(i)) for i in k]) if np.ndim(k) else fn(int(k))

    def window(self, k, w: int) -> np.ndarray:  # [w, H, W] ([B, w, H, W])
        return self._each(k, lambda i: self.spikes[i - w // 2 : i - w // 2 + w])

    def tfp(self, k, w: int) -> np.ndarray:  # [H, W] ([B, H, W])
        return self.window(k, w).mean(axis=-3, dtype=np.float32)

    def tfi(self, k) -> np.ndarray:  # 1 / (first spike after k - last at or before k)
        def one(i: int) -> np.ndarray:
            back = np.argmax(self.spikes[: i + 1][::-1], axis=0)  # 0 where there is none
            ahead = np.argmax(self.spikes[i + 1 :], axis=0) + 1
            return (1.0 / (back + ahead)).astype(np.float32)

        return self._each(k, one)


def sliding_camera(height: int, width: int, gain: float = 0.25):
    """Firing rates [H, W] at readout k: skimage's camera image, one pixel further right every 8."""
    image = data.camera()[::4, ::4].astype(np.float32) / 255.0  # [128, 128]
    return lambda k: gain * image[40 : 40 + height, 30 + k // 8 : 30 + k // 8 + width]


TRAIN = {"steps": 30, "batch_size": 4, "crop": 16, "progress": False}


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def scene():
    rates = sliding_camera(24, 40)
    return rates, BernoulliStream(rates, 110)


@pytest.fixture(scope="module")
def trained(scene):
    stream = scene[1]
    return train_sim(stream, valid_timestamps(stream, 33), 33, seed=3, **TRAIN)


def _spikes(*shape, seed=0):
    return (torch.rand(*shape, generator=torch.Generator().manual_seed(seed)) < 0.3).float()


def _random_sim(**kwargs) -> SIM:
    """A SIM whose output layer has PyTorch's random start: a fresh SIM's is zero (its output 0
    whatever it sees), which would hide what each pixel's output depends on."""
    model = SIM(**kwargs)
    model.head[-1].reset_parameters()
    return model


def test_parameter_count():
    n = SIM().num_parameters()
    print(f"SIM parameters: {n}")
    assert 15_000 <= n <= 45_000


def test_a_sim_is_float32_whatever_torchs_default_dtype(float64_default):
    """A script whose torch default dtype is float64 made float64 weights, which refused the
    float32 spike windows that train them ("SIM input expected dtype torch.float64")."""
    torch.manual_seed(0)
    wide = SIM(window=5)
    torch.set_default_dtype(torch.float32)
    torch.manual_seed(0)
    plain = SIM(window=5)
    assert {p.dtype for p in wide.parameters()} == {torch.float32}
    assert all(torch.equal(a, b) for a, b in zip(wide.parameters(), plain.parameters()))


@pytest.mark.parametrize("layers", [1, 3])
def test_field_is_the_square_an_output_depends_on(layers):
    torch.manual_seed(0)
    model = _random_sim(window=3, shift_layers=layers)
    x = _spikes(1, 3, 31, 31).requires_grad_()
    model(x)[0, 0, 15, 15].backward()
    rows, cols = (x.grad.abs().sum((0, 1)) > 0).nonzero().T
    assert rows.max() - rows.min() + 1 == cols.max() - cols.min() + 1 == model.field()


def test_a_crop_under_the_field_is_warned_of(scene):
    """A 4² crop trains on the zero border, inferred on whole frames: said, once."""
    stream, ts = scene[1], valid_timestamps(scene[1], 33)
    said = (
        r"SIM crop 4: under the 15-pixel square .* \(sim-train --crop, a method config's sim.crop\)"
    )
    with pytest.warns(UserWarning, match=said) as caught:  # (the option named: the SIM trial)
        train_sim(stream, ts, 33, steps=1, batch_size=1, crop=4, progress=False)
    assert len(caught) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a crop of the field, or the whole of a smaller frame
        train_sim(stream, ts, 33, steps=1, batch_size=1, crop=15, progress=False)
        small = BernoulliStream(lambda k: np.full((8, 6), 0.2), 60)
        train_sim(small, valid_timestamps(small, 33), 33, steps=1, crop=64, progress=False)


def _sees_every_other_pixel(height: int, width: int, layers: int) -> bool:
    """Whether every output of a SIM with `layers` shift layers on `height`×`width` frames
    depends on every pixel but its own (its gradient, positive weights: no path cancels)."""
    model = SIM(window=3, shift_layers=layers).double().train()
    with torch.no_grad():  # (SIM starts at zero)
        for weights in model.parameters():
            weights.copy_(torch.rand_like(weights) * 0.1 + 0.01)
    x = torch.rand(1, 3, height, width, dtype=torch.float64, requires_grad=True)
    out = model(x)[0, 0]  # [H, W]
    for y, x_ in np.ndindex(height, width):
        (grad,) = torch.autograd.grad(out[y, x_], x, retain_graph=True)
        if int((grad.abs().sum((0, 1)) > 0).sum()) < height * width - 1:
            return False
    return True


@pytest.mark.parametrize("height, width", [(2, 2), (1, 5), (3, 3), (5, 3), (8, 6), (4, 9)])
def test_spanning_layers_are_the_fewest_that_see_every_pixel(height, width):
    """SIM.spanning_layers, the count past which train_sim warns, measured: the fewest shift
    layers whose every output sees every other pixel (a corner's field: 2m + 1 rows down and m
    columns across)."""
    layers = SIM.spanning_layers(height, width)
    assert _sees_every_other_pixel(height, width, layers)
    assert layers == 1 or not _sees_every_other_pixel(height, width, layers - 1)


def test_shift_layers_past_the_frame_are_warned_of():
    """On an 8×6 frame 5 shift layers reach every pixel from every other: a 6th is said to add
    the zero border only, with the number that suffices; 5 are not."""
    small = BernoulliStream(lambda k: np.full((8, 6), 0.2), 60)
    ts = valid_timestamps(small, 33)
    said = r"shift_layers 6 on 8×6 frames: 5 reach every.* \(a method config's; sim-train trains"
    with pytest.warns(UserWarning, match=said) as caught:
        train_sim(small, ts, 33, steps=1, crop=64, progress=False, shift_layers=6)
    assert len(caught) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        train_sim(small, ts, 33, steps=1, crop=64, progress=False, shift_layers=5)


@pytest.mark.parametrize("path", ["forward", "forward_rotated"])
@pytest.mark.parametrize("pixel", [(9, 10), (0, 0), (17, 20)])
def test_blind_spot_is_exact(path, pixel):
    torch.manual_seed(0)
    model = _random_sim()
    x = _spikes(2, 33, 18, 21).requires_grad_()
    i, j = pixel
    getattr(model, path)(x)[0, 0, i, j].backward()
    grad = x.grad.abs()  # [2, 33, 18, 21]
    assert grad[1].sum() == 0  # other batch items are not seen
    assert (grad[0, :, i, j] == 0).all()  # no time channel of the pixel itself
    field = grad[0].sum(0) > 0  # [18, 21]
    assert field.sum() > 9  # more than a 3×3 neighbourhood
    if pixel == (9, 10):  # interior: all four half planes, each 7 deep, 15×15 cross in all
        for di, dj in [(-1, 0), (1, 0), (0, -1), (0, 1), (-7, 0), (7, 3), (-3, 7), (2, -7)]:
            assert field[i + di, j + dj], (di, dj)
        assert not field[i - 4, j - 4] and not field[i + 7, j + 4]
        assert field.sum() == 15 * 15 - 4 * 4 * 4 - 1


@pytest.mark.parametrize("size", [(1, 1), (7, 5), (13, 32)])
def test_training_path_matches_inference_and_the_rotated_gradients(size):
    """SIM trains through `forward_rotated` and infers through `forward`: `forward` gives the
    same values with and without autograd, and the literal network's weight gradients."""
    torch.manual_seed(2)
    model = _random_sim().train()
    x = _spikes(2, 33, *size)
    y = model(x)
    with torch.no_grad():
        assert torch.equal(y, model(x))
    grads = []
    for path in (model.forward, model.forward_rotated):
        model.zero_grad()
        (path(x) * _spikes(*y.shape, seed=3)).sum().backward()
        grads.append([p.grad.clone() for p in model.parameters()])
    for fast, literal in zip(*grads):
        assert torch.allclose(fast, literal, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("size", [(1, 1), (2, 9), (7, 5), (13, 32), (32, 13)])
def test_shapes_and_paths_agree(size):
    torch.manual_seed(1)
    model = _random_sim(out_channels=3).eval()
    x = _spikes(2, 33, *size)
    with torch.no_grad():
        y = model(x)
        assert y.shape == (2, 3, *size)
        assert torch.allclose(y, model.forward_rotated(x), atol=1e-6)
        assert model.forward_rotated(x, square=True).shape == y.shape
    fast = inference_model(model, torch.bfloat16)
    bf16 = predict(fast, x.to(torch.uint8).numpy())  # [2, H, W, 3]
    assert bf16.shape == (2, *size, 3) and bf16.dtype == np.float32
    assert np.abs(bf16 - y.permute(0, 2, 3, 1).numpy()).max() < 0.02


def test_training_lowers_the_loss_and_is_deterministic(scene, trained):
    model, losses = trained
    assert not model.training
    assert np.mean(losses[-5:]) < 0.7 * np.mean(losses[:5])
    again, losses_again = train_sim(scene[1], valid_timestamps(scene[1], 33), 33, seed=3, **TRAIN)
    assert losses_again == losses
    for a, b in zip(model.parameters(), again.parameters()):
        assert torch.equal(a, b)


def test_float32_training_runs_channels_first_to_the_same_sim(scene, monkeypatch):
    """Without bfloat16 SIM trains channels-first (faster on AVX2); channels-last, the layout
    of bfloat16 training and of inference, learns the same network but for the last bits."""
    ts = valid_timestamps(scene[1], 33)
    first, losses = train_sim(scene[1], ts, 33, seed=3, bf16=False, **TRAIN)
    assert next(first.parameters()).is_contiguous()
    monkeypatch.setattr(sim_train, "training_layout", lambda bf16: torch.channels_last)
    last, losses_last = train_sim(scene[1], ts, 33, seed=3, bf16=False, **TRAIN)
    assert last.shift[0].weight.is_contiguous(memory_format=torch.channels_last)
    np.testing.assert_allclose(losses_last, losses, rtol=1e-4)
    for a, b in zip(first.parameters(), last.parameters()):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)


def test_save_load_round_trip_and_reuse(tmp_path, scene, trained, capsys):
    model = trained[0]
    path = tmp_path / "run" / "sim.pt"
    save_sim(model, path, steps=TRAIN["steps"])
    loaded = load_sim(path)
    x = _spikes(1, 33, 11, 14)
    for a, b in zip(loaded.state_dict().values(), model.state_dict().values()):
        assert torch.equal(a, b)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x), model(x))  # layouts differ: last-bit changes only
    stray = tmp_path / "stray.pt"
    torch.save({"weights": [1.0]}, stray)  # another tool's file: said, not a KeyError
    with pytest.raises(ValueError, match=f"{stray}: not a saved SIM"):
        load_sim(stray)
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_sim(tmp_path / "missing.pt")
    stream, ts = scene[1], [40, 50]
    tiny = dict(steps=2, batch_size=1, crop=16, progress=False)
    capsys.readouterr()
    first, seconds, _ = train_or_load(path, stream, ts, 33, **tiny)  # no fingerprint: trained
    assert seconds > 0
    said = capsys.readouterr().err  # no progress bar: a line as SIM's training starts and ends
    assert f"SIM: training -> {path}\nSIM: trained 2 steps in " in said
    reused, seconds, _ = train_or_load(path, stream, ts, 33, **tiny)
    assert seconds == 0 and torch.equal(reused.head[-1].bias, first.head[-1].bias)
    assert "SIM:" not in capsys.readouterr().err  # loaded: nothing said
    assert train_or_load(path, stream, ts, 33, force=True, **tiny)[1] > 0  # --force: retrained
    payload = torch.load(path, weights_only=True)  # a SIM saved before every readout was hashed
    payload["meta"]["data"] = spikes_fingerprint(stream, ts, sampled=True)
    torch.save(payload, path)
    assert train_or_load(path, stream, ts, 33, **tiny)[1] == 0  # still its spikes': reused
    other = BernoulliStream(scene[0], len(stream), seed=1)
    # other spikes, other timestamps, each against the cache of (stream, ts)'s SIM (against the
    # other spikes' SIM, other timestamps were retrained whether they were hashed or not)
    for changed in ((other, ts), (stream, [40, 51])):
        train_or_load(path, stream, ts, 33, **tiny)
        assert train_or_load(path, *changed, 33, **tiny)[1] > 0
    train_or_load(path, stream, ts, 33, **tiny)
    payload = torch.load(path, weights_only=True)
    del payload["meta"]["start"]  # a SIM cached before SIM started at zero: retrained
    torch.save(payload, path)
    capsys.readouterr()
    assert train_or_load(path, stream, ts, 33, **tiny)[1] > 0
    assert capsys.readouterr().err.count("training SIM afresh") == 1  # (said twice, with the lock)
    path.write_bytes(path.read_bytes()[:1000])  # cut short (written before saves were atomic)
    assert train_or_load(path, stream, ts, 33, **tiny)[1] > 0  # retrained, and saved whole
    torch.save({"weights": torch.zeros(3)}, path)  # a readable file of another kind: a KeyError
    capsys.readouterr()
    assert train_or_load(path, stream, ts, 33, **tiny)[1] > 0
    assert "not a saved SIM; training SIM afresh" in capsys.readouterr().err
    assert train_or_load(path, stream, ts, 33, **tiny)[1] == 0
    # a SIM's file edited, or another version's: its architecture or weights no SIM's (torch's
    # TypeError or RuntimeError, naming no file, ended the run that read the cache)
    good = torch.load(path, weights_only=True)
    for edit in ({"config": {**good["config"], "bogus": 1}}, {"state_dict": {}}):
        torch.save({**good, **edit}, stray)
        with pytest.raises(ValueError, match=f"{stray}: not a saved SIM's architecture or weig"):
            load_sim(stray)
        torch.save({**good, **edit}, path)
        capsys.readouterr()
        assert train_or_load(path, stream, ts, 33, **tiny)[1] > 0
        assert "architecture or weights (" in capsys.readouterr().err
    # other training settings at the same path: a cache's retrained, said why (it was reused,
    # steps and all); a file the user named (sim-train --out FILE: `keep`) refused, unless
    # forced (it was replaced)
    capsys.readouterr()
    other = {**tiny, "steps": 3, "seed": 7}
    with pytest.raises(FileExistsError, match=r"a SIM trained with other settings \(steps 2, now"):
        train_or_load(path, stream, ts, 33, keep=True, **other)
    torch.save({**good, "state_dict": {}}, stray)  # (said "a SIM not a saved SIM's architecture")
    with pytest.raises(FileExistsError, match=f"{stray}: not a saved SIM's architecture or weig"):
        train_or_load(stray, stream, ts, 33, keep=True, **tiny)
    assert torch.load(path, weights_only=True)["meta"]["steps"] == 2
    assert train_or_load(path, stream, ts, 33, keep=True, **tiny)[1] == 0  # its own: reused
    assert train_or_load(path, stream, ts, 33, **other)[1] > 0
    assert "trained with other settings (steps 2, now 3, seed" in capsys.readouterr().err
    assert torch.load(path, weights_only=True)["meta"]["steps"] == 3
    # the thread count it trained at, recorded (SIM trained at another is another SIM, unsaid
    # where cached); reused at another all the same, as the settings are
    meta = torch.load(path, weights_only=True)["meta"]
    assert meta["threads"] == torch.get_num_threads()
    assert meta["bf16"] == bf16_is_fast()  # (another SIM, too, with and without it)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(threads + 1)
        assert train_or_load(path, stream, ts, 33, **other)[1] == 0
    finally:
        torch.set_num_threads(threads)
    assert train_or_load(path, stream, ts, 33, keep=True, force=True, **tiny)[1] > 0
    # no temporary file left (the lock file that one process a SIM takes stays, empty)
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name, f"{path.name}.lock"]


@contextlib.contextmanager
def _saved_meanwhile(saved: Path, path: Path):
    """For a `with` block: another process alike (a thread) holding `path`'s SIM lock, as one
    training it does, that copies `saved` to `path` as it lets go; the block runs once it holds
    the lock."""
    holding = threading.Event()

    def other_process():
        with exclusive_lock(path.with_name(f"{path.name}.lock"), busy="busy"):
            holding.set()
            time.sleep(0.5)
            shutil.copy(saved, path)

    other = threading.Thread(target=other_process)
    other.start()
    holding.wait()
    try:
        yield
    finally:
        other.join()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="flock is POSIX")
def test_a_sim_that_another_process_trains_is_waited_for_and_loaded(tmp_path, scene, monkeypatch):
    """Two methods started together on one dataset each trained the same SIM, and the second to
    finish overwrote the first's."""
    stream, ts = scene[1], [40, 50]
    tiny = dict(steps=2, batch_size=1, crop=16, progress=False)
    elsewhere, _, _ = train_or_load(tmp_path / "other" / "sim.pt", stream, ts, 33, **tiny)
    monkeypatch.setattr("spikegs.sim_train.train_sim", lambda *a, **k: pytest.fail("trained"))
    path = tmp_path / "sim.pt"
    with _saved_meanwhile(tmp_path / "other" / "sim.pt", path):
        model, seconds, _ = train_or_load(path, stream, ts, 33, **tiny)
    assert seconds == 0 and torch.equal(model.head[-1].bias, elsewhere.head[-1].bias)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="flock is POSIX")
def test_a_named_file_another_process_saves_meanwhile_is_kept(tmp_path, scene, monkeypatch):
    """Two `sim-train --out FILE` at once on other datasets: the second, once the first's lock
    was released, took the first's SIM for a stale cache and trained over it (refused when run
    after it, as a file the user named is)."""
    stream, ts = scene[1], [40, 50]
    tiny = dict(steps=2, batch_size=1, crop=16, progress=False)
    train_or_load(tmp_path / "other" / "sim.pt", stream, [40, 51], 33, **tiny)
    monkeypatch.setattr("spikegs.sim_train.train_sim", lambda *a, **k: pytest.fail("trained"))
    path = tmp_path / "sim.pt"
    with _saved_meanwhile(tmp_path / "other" / "sim.pt", path):  # another SIM at the same --out
        with pytest.raises(FileExistsError, match="trained on other spikes.* which training wo"):
            train_or_load(path, stream, ts, 33, keep=True, **tiny)
    assert filecmp.cmp(path, tmp_path / "other" / "sim.pt", shallow=False)


def test_a_sim_trained_over_another_takes_its_scores_away(tmp_path, scene):
    """A SIM trained again at its path (new spikes or timestamps: `spikegs poses` drops some)
    left beside it the record `spikegs sim-train` wrote of the one before, NAME.json, whose
    scores and seconds were then read as the new SIM's."""
    path = tmp_path / "sim.pt"
    stream, tiny = scene[1], dict(steps=2, batch_size=1, crop=16, progress=False)
    train_or_load(path, stream, [40, 50], 33, **tiny)
    record = tmp_path / "sim.pt.json"
    record.write_text('{"scores": {}}')  # sim-train's
    assert train_or_load(path, stream, [40, 50], 33, **tiny)[1] == 0  # reused: still its own
    assert record.exists()
    assert train_or_load(path, stream, [40, 51], 33, **tiny)[1] > 0
    assert not record.exists()


def test_sim_of_a_read_only_dataset_is_cached_in_the_users_cache(scene, tmp_path, monkeypatch):
    """A dataset folder that cannot be written (a read-only mount) ended SIM's training in a
    traceback from torch.save, and `spikegs train` could not train a SIM method on it at all."""
    dataset_sim = tmp_path / "dataset" / "sim"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(
        "spikegs.sim_train.writable_folder",
        lambda folder: Path(folder) != dataset_sim and writable_folder(folder),
    )
    stream, ts = scene[1], [40, 50]
    tiny = dict(steps=2, batch_size=1, crop=16, progress=False)
    model, seconds, path = train_or_load(dataset_sim / "sim.pt", stream, ts, 33, **tiny)
    assert seconds > 0 and not dataset_sim.exists()
    assert path.name == "sim.pt" and path.is_relative_to(tmp_path / "cache" / "spikegs" / "sim")
    again, seconds, same = train_or_load(dataset_sim / "sim.pt", stream, ts, 33, **tiny)
    assert seconds == 0 and same == path  # found there the next time
    assert torch.equal(again.head[-1].bias, model.head[-1].bias)
    # a SIM cached there before every readout was hashed: under its sampled fingerprint's folder
    sampled = spikes_fingerprint(stream, ts, sampled=True)
    legacy = user_cache("sim.pt", sampled)
    legacy.parent.mkdir(parents=True)
    payload = torch.load(path, weights_only=True)
    payload["meta"]["data"] = sampled
    torch.save(payload, legacy)
    path.unlink()
    assert train_or_load(dataset_sim / "sim.pt", stream, ts, 33, **tiny)[1:] == (0, legacy)
    # an alternate of the same spikes (the raw spikes' SIM where none is repaired) cached there:
    # read, not trained again (it was, beside it)
    raw = train_or_load(dataset_sim / "raw.pt", stream, ts, 33, **tiny)[2]
    assert train_or_load(
        dataset_sim / "sim2.pt", stream, ts, 33, alternates=[dataset_sim / "raw.pt"], **tiny
    )[1:] == (0, raw)
    other = BernoulliStream(scene[0], len(stream), seed=1)  # other spikes: another folder
    assert train_or_load(dataset_sim / "sim.pt", other, ts, 33, **tiny)[2] != path
    # the folder writable again: the SIM cached meanwhile is read there (it was trained again),
    # not for a file the user named (the sim-train trial)
    with monkeypatch.context() as writable:
        writable.setattr("spikegs.sim_train.writable_folder", writable_folder)
        assert train_or_load(dataset_sim / "raw.pt", stream, ts, 33, **tiny)[1:] == (0, raw)
        named = train_or_load(dataset_sim / "raw.pt", stream, ts, 33, keep=True, **tiny)
        assert named[1] > 0 and named[2] == dataset_sim / "raw.pt"
    # a file the user named (sim-train --out, `keep`) in a folder that cannot be written: its
    # cache stand-in holding a SIM of other settings is a cache, trained over (it was refused as
    # the named file, "--force trains afresh over it, or give another --out")
    named = dataset_sim / "mine.pt"
    stale = train_or_load(named, stream, ts, 33, **{**tiny, "steps": 3})[2]
    assert train_or_load(named, stream, ts, 33, keep=True, **tiny)[1:] != (0, stale)
    assert torch.load(stale, weights_only=True)["meta"]["steps"] == 2
    # a cache that cannot be written either: refused before training (XDG_CACHE_HOME a file)
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "file"))
    monkeypatch.setattr("spikegs.sim_train.train_sim", lambda *a, **k: pytest.fail("trained"))
    with pytest.raises(OSError, match="set XDG_CACHE_HOME to a writable folder"):
        train_or_load(dataset_sim / "sim.pt", other, [41, 50], 33, **tiny)
    monkeypatch.setenv("XDG_CACHE_HOME", "relative")  # ignored, as the XDG spec says
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert (
        user_cache("s.pt", "ab") == tmp_path / "home" / ".cache" / "spikegs" / "sim" / "ab" / "s.pt"
    )


def test_writable_folder(tmp_path):
    assert writable_folder(tmp_path) and writable_folder(tmp_path / "new" / "deeper")
    (tmp_path / "file").write_text("")
    assert not writable_folder(tmp_path / "file") and not writable_folder(tmp_path / "file" / "x")
    if Path("/proc/self").is_dir():  # os.access says yes to root; creating a file there fails
        assert not writable_folder(Path("/proc/new"))


class _CtrlC:
    """`stream`, whose `at`-th training window (not a fingerprint's one-readout window) is
    interrupted by a Ctrl-C (None: none is); `calls` counts them."""

    def __init__(self, stream, at: int | None):
        self.stream, self.at, self.height, self.width = stream, at, stream.height, stream.width
        self.calls = 0

    def __len__(self) -> int:
        return len(self.stream)

    def digest(self) -> bytes:
        return self.stream.digest()

    def window(self, k, w: int) -> np.ndarray:
        if w > 1:
            self.calls += 1
            if self.calls == self.at:
                raise KeyboardInterrupt
        return self.stream.window(k, w)


class _SigInt(_CtrlC):
    """`stream`, whose `at`-th training window sends this process a SIGINT (a Ctrl-C in the
    middle of a step)."""

    signum = signal.SIGINT

    def window(self, k, w: int) -> np.ndarray:
        if w > 1:
            self.calls += 1
            if self.calls == self.at:
                os.kill(os.getpid(), self.signum)
        return self.stream.window(k, w)


class _SigTerm(_SigInt):
    """A SIGTERM (a batch scheduler's time limit) in the middle of a step."""

    signum = signal.SIGTERM


def test_sim_saves_its_state_on_sigterm(tmp_path, capsys, scene):
    """SIGTERM as the `spikegs` command raises it: the step finishes, the state is saved, and
    SIM's training stops as Terminated (exit 143: a KeyboardInterrupt said 'interrupted', 130)."""
    stream, path = scene[1], tmp_path / "sim.pt"
    ts = valid_timestamps(stream, 33)
    previous = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        with pytest.raises(Terminated):
            at = 12 * TRAIN["batch_size"] + 1
            train_or_load(path, _SigTerm(stream, at), ts, 33, seed=3, **TRAIN)
        assert signal.getsignal(signal.SIGTERM) is raise_terminated
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert "SIGTERM: SIM's training stops after this step" in capsys.readouterr().err
    assert torch.load(path.with_name("sim.pt.partial"), weights_only=True)["step"] == 13


class _GoneAt(_CtrlC):
    """`stream`, whose `at`-th training window sets `stderr` gone (its reader leaving)."""

    def __init__(self, stream, at: int, stderr):
        super().__init__(stream, None)
        self.gone_at, self.stderr = at, stderr

    def window(self, k, w: int) -> np.ndarray:
        if w > 1:
            self.calls += 1
            self.stderr.gone |= self.calls == self.gone_at
        return self.stream.window(k, w)


def test_sim_saves_its_state_where_its_bar_output_is_gone(
    tmp_path, monkeypatch, scene, trained, gone_stderr
):
    """`spikegs sim-train ... 2>&1 | head`: the bar's write after the reader left raised
    BrokenPipeError, the steps since the last 30-second save lost; now the step finishes, the
    state is saved, then it stops with that error, and resumes to the SIM of a run never
    stopped."""
    every_step = functools.partial(sim_train.tqdm, mininterval=0, miniters=1)
    monkeypatch.setattr(sim_train, "tqdm", every_step)  # (a write at each step)
    stream, path = scene[1], tmp_path / "sim.pt"
    ts = valid_timestamps(stream, 33)
    stderr = gone_stderr(BrokenPipeError(errno.EPIPE, "Broken pipe"))
    gone = _GoneAt(stream, 12 * TRAIN["batch_size"] + 1, stderr)
    with pytest.raises(BrokenPipeError):
        train_or_load(path, gone, ts, 33, seed=3, **{**TRAIN, "progress": True})
    assert torch.load(path.with_name("sim.pt.partial"), weights_only=True)["step"] == 13
    monkeypatch.undo()
    resumed, _, _ = train_or_load(path, stream, ts, 33, seed=3, **TRAIN)
    for a, b in zip(resumed.state_dict().values(), trained[0].state_dict().values()):
        assert torch.equal(a, b)


def test_sim_saves_its_state_on_ctrl_c(tmp_path, capsys, scene, trained, ctrl_c):
    """A Ctrl-C in SIM's training lost everything since the last 30-second save (a process
    killed sooner made no progress at all): the step finishes, the state is saved, then it stops
    (`ctrl_c`: run from a background job, the suite inherited SIGINT ignored and this failed)."""
    stream, path = scene[1], tmp_path / "sim.pt"
    ts = valid_timestamps(stream, 33)
    with pytest.raises(KeyboardInterrupt):  # the 30 s have not passed: saved for the Ctrl-C
        train_or_load(path, _SigInt(stream, 12 * TRAIN["batch_size"] + 1), ts, 33, seed=3, **TRAIN)
    assert "SIM's training stops after this step, its state saved" in capsys.readouterr().err
    assert torch.load(path.with_name("sim.pt.partial"), weights_only=True)["step"] == 13
    # without a checkpoint (bench sim's) no state is saved, nor said to be
    with pytest.raises(KeyboardInterrupt):
        train_sim(_SigInt(stream, 12 * TRAIN["batch_size"] + 1), ts, 33, seed=3, **TRAIN)
    assert (
        capsys.readouterr().err.strip().startswith("Ctrl-C: SIM's training stops after this step (")
    )
    resumed, _, _ = train_or_load(path, stream, ts, 33, seed=3, **TRAIN)
    for a, b in zip(resumed.state_dict().values(), trained[0].state_dict().values()):
        assert torch.equal(a, b)
    path.unlink()  # in the last step too: it stops (training went on to the Gaussians)
    last = (TRAIN["steps"] - 1) * TRAIN["batch_size"] + 1
    with pytest.raises(KeyboardInterrupt):
        train_or_load(path, _SigInt(stream, last), ts, 33, seed=3, **TRAIN)
    assert torch.load(path.with_name("sim.pt.partial"), weights_only=True)["step"] == TRAIN["steps"]


def test_interrupted_sim_training_resumes_to_the_same_sim(
    tmp_path, monkeypatch, capsys, scene, trained
):
    """Ctrl-C in step 13 of 30: the state saved after step 12 resumes to the SIM (and losses)
    of a run never interrupted; another setting starts afresh."""
    monkeypatch.setattr("spikegs.sim_train.CHECKPOINT_S", 0.0)  # state saved every step
    stream, path = scene[1], tmp_path / "sim" / "sim.pt"  # a folder not made yet
    ts = valid_timestamps(stream, 33)
    with pytest.raises(KeyboardInterrupt):
        train_or_load(path, _CtrlC(stream, 12 * TRAIN["batch_size"] + 1), ts, 33, seed=3, **TRAIN)
    partial = path.with_name("sim.pt.partial")
    state = torch.load(partial, weights_only=True)
    assert state["step"] == 12 and not path.exists()
    # what processes killed while saving the state or the SIM left (swept once the lock is held)
    killed = [path.with_name(".sim.pt.partial.999999.tmp"), path.with_name(".sim.pt.999998.tmp")]
    for leftover in killed:
        leftover.write_bytes(b"half")
    state["seconds"] = 1000.0  # the interrupted process's training time counts
    torch.save(state, partial)
    resumed, seconds, _ = train_or_load(path, stream, ts, 33, seed=3, **TRAIN)
    assert "resumes at step 12 of 30" in capsys.readouterr().err
    assert 1000 < seconds == torch.load(path, weights_only=True)["meta"]["seconds"] < 1100
    for a, b in zip(resumed.state_dict().values(), trained[0].state_dict().values()):
        assert torch.equal(a, b)
    assert torch.load(path, weights_only=True)["meta"]["final_loss"] == np.mean(trained[1][-50:])
    assert not partial.exists() and not any(p.exists() for p in killed)
    path.unlink()
    with pytest.raises(KeyboardInterrupt):  # a state saved for crop 16 ...
        train_or_load(path, _CtrlC(stream, 9), ts, 33, seed=3, **TRAIN)
    other = dict(TRAIN, crop=20)  # ... is not resumed for crop 20: trained afresh, said (an
    fresh, _ = train_sim(stream, ts, 33, seed=3, **other)  # earlier version's was dropped unsaid)
    capsys.readouterr()
    afresh, _, _ = train_or_load(path, stream, ts, 33, seed=3, **other)
    assert "an interrupted SIM training of other settings" in capsys.readouterr().err
    for a, b in zip(afresh.state_dict().values(), fresh.state_dict().values()):
        assert torch.equal(a, b)


def test_inference_over_timestamps(scene, trained):
    model, stream = trained[0], scene[1]
    ts = np.array([40, 50, 60])
    images = infer_sim(model, stream, ts, batch_size=2, dtype=torch.float32)  # [3, H, W, 1]
    assert images.shape == (3, stream.height, stream.width, 1)
    with torch.no_grad():
        direct = model(torch.from_numpy(stream.window(ts, 33)).float())
    np.testing.assert_allclose(images[..., 0], direct[:, 0].numpy(), atol=1e-5)


def test_compare_methods_reports_all(scene, trained):
    rates, stream = scene
    ts = np.array([40, 70])
    gt = np.stack([rates(k) for k in ts])  # [2, H, W]
    scores = compare_methods(trained[0], [stream], ts, gt[..., None])
    assert set(scores) == {"SIM", "TFP(33)", "TFP(65)", "TFI"}
    assert all(np.isfinite(s["psnr"]) and -1 <= s["ssim"] <= 1 for s in scores.values())
    # each row the images it names (TFP(65) computed over 33 readouts passed)
    for name, images in (
        ("TFP(33)", stream.tfp(ts, 33)),
        ("TFP(65)", stream.tfp(ts, 65)),
        ("TFI", stream.tfi(ts)),
    ):
        expected = np.mean([psnr(p, g) for p, g in zip(images, gt)])
        assert scores[name]["psnr"] == pytest.approx(expected, rel=1e-12), name
    assert scores["TFP(65)"]["psnr"] != scores["TFP(33)"]["psnr"]
    # a pseudo ground truth, TFP(65) of the view's own spikes, scored TFP(65) inf (with a numpy
    # warning): that method leaves out that view (whatever was repaired in it since: it was
    # left out only where equal), and a method left no view is left out
    pseudo = gt.copy()
    pseudo[1] = stream.tfp(ts[1], 65) * 1.01  # (as a flicker's division or a repair leaves it)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mixed = compare_methods(trained[0], [stream], ts, pseudo[..., None], own=[None, "TFP(65)"])
    assert mixed["TFP(65)"]["psnr"] == pytest.approx(psnr(stream.tfp(ts[0], 65), gt[0]))
    assert mixed["TFP(33)"] != scores["TFP(33)"]  # scored on both views, one ground truth new
    alone = compare_methods(trained[0], [stream], ts, stream.tfp(ts, 65)[..., None])  # (equal)
    assert set(alone) == {"SIM", "TFP(33)", "TFI"}


def test_compare_methods_divide_each_image_by_the_flicker_over_its_readouts(scene):
    """Given the light's flicker, each method's image is divided by the light's mean over the
    readouts it shows (TFP(w): the w centred on t; TFI: t + 0.5; SIM: its target window), as
    training's targets are: the rows met a steady ground truth with the flicker's phase left in."""
    from spikegs.flicker import Flicker

    rates, stream = scene
    ts = np.array([40, 70])
    gt = np.stack([rates(k) for k in ts])  # [2, H, W]
    model = _random_sim(window=33, target_window=17)
    with torch.no_grad():  # (its random start's output is below 0 here, clamped to 0 throughout)
        model.head[-1].bias.fill_(0.3)
    flicker = Flicker(depth=0.5, period=50.0, phase=0.3)
    scores = compare_methods(model, [stream], ts, gt[..., None], flicker=flicker)

    def light(first, span):  # [2] the mean of 1 + depth sin over readouts first .. + span - 1
        t = first[:, None] + np.arange(span)
        return np.mean(1 + 0.5 * np.sin(2 * np.pi * t / 50.0 + 0.3), axis=1)

    for name, images, gain in (
        ("SIM", infer_sim(model, stream, ts)[..., 0], light(ts - 8, 17)),
        ("TFP(33)", stream.tfp(ts, 33), light(ts - 16, 33)),
        ("TFP(65)", stream.tfp(ts, 65), light(ts - 32, 65)),
        ("TFI", stream.tfi(ts), light(ts + 0.5, 1)),
    ):
        expected = np.mean([psnr(p / g, t) for p, g, t in zip(images, gain, gt)])
        assert scores[name]["psnr"] == pytest.approx(expected, rel=1e-5), name
    # a dataset that kept no name, its pseudo ground truth the view's own TFP(65) as the spikes
    # show it (made before the flicker was divided out of it): that row still leaves it out
    alone = compare_methods(model, [stream], ts, stream.tfp(ts, 65)[..., None], flicker=flicker)
    assert set(alone) == {"SIM", "TFP(33)", "TFI"}


def test_metrics():
    gt = np.random.default_rng(0).random((16, 20)).astype(np.float32)
    assert psnr(gt + 0.1, gt) == pytest.approx(20.0, abs=1e-4)
    assert ssim(gt, gt) == pytest.approx(1.0)
    assert ssim(np.stack([gt] * 3, -1), np.stack([gt] * 3, -1)) == pytest.approx(1.0)
    with pytest.raises(ValueError):
        psnr(gt, gt[:-1])
    noisy = np.clip(gt + 0.05, 0, 1)
    assert ssim(noisy, gt) == pytest.approx(structural_similarity(gt, noisy, data_range=1.0))
    for shape in ((1, 20), (20, 1), (1, 20, 3), (5, 20), (3, 4)):  # line images, small sides
        image = np.random.default_rng(1).random(shape)
        assert 0 < ssim(np.clip(image + 0.05, 0, 1), image) < ssim(image, image) == 1.0
    for shape in ((2, 20), (1, 1)):
        with pytest.raises(ValueError, match="SSIM needs sides"):
            ssim(gt[: shape[0], : shape[1]], gt[: shape[0], : shape[1]])


def test_ssim_uses_a_7x7_window_and_shrinks_it_only_for_small_images():
    """The reported SSIM is scikit-image's with a 7x7 window on images of 7 px or more a side,
    the largest odd window on smaller ones (5 on a 5x12 image). A fixed 3x3 window moved this
    pair's score from 0.8232 to 0.7957."""
    rng = np.random.default_rng(0)
    gt = rng.random((16, 16, 3))
    pred = np.clip(gt + 0.2 * rng.standard_normal(gt.shape), 0, 1)
    want = structural_similarity(gt, pred, data_range=1.0, channel_axis=-1, win_size=7)
    assert ssim(pred, gt) == pytest.approx(want, abs=1e-12)
    small_gt, small_pred = gt[:5, :12, 0], pred[:5, :12, 0]
    want = structural_similarity(small_gt, small_pred, data_range=1.0, win_size=5)
    assert ssim(small_pred, small_gt) == pytest.approx(want, abs=1e-12)


def test_ssim_3dgs_is_3dgs_evaluations_ssim():
    """eval.json's ssim_3dgs: 3DGS's formula (11x11 Gaussian window, sigma 1.5, zero padding, the
    mean over every pixel and channel), checked against scipy's correlation of the same window;
    the scikit-image SSIM beside it is another number (a 7x7 uniform window, borders cropped)."""
    from scipy.ndimage import correlate

    rng = np.random.default_rng(0)
    gt = rng.random((20, 24, 3))
    pred = np.clip(gt + 0.2 * rng.standard_normal(gt.shape), 0, 1)
    g = np.exp(-((np.arange(11) - 5.0) ** 2) / (2 * 1.5**2))
    window = np.outer(g, g) / np.outer(g, g).sum()  # [11, 11]

    def blur(x):  # [H, W] -> [H, W], zeros outside
        return correlate(x, window, mode="constant", cval=0.0)

    maps = []
    for c in range(3):
        x, y = pred[..., c], gt[..., c]
        mx, my = blur(x), blur(y)
        vx, vy, cxy = blur(x * x) - mx**2, blur(y * y) - my**2, blur(x * y) - mx * my
        c1, c2 = 0.01**2, 0.03**2
        maps.append((2 * mx * my + c1) * (2 * cxy + c2) / ((mx**2 + my**2 + c1) * (vx + vy + c2)))
    assert ssim_3dgs(pred, gt) == pytest.approx(np.mean(maps), abs=1e-7)  # (float32 window taps)
    assert ssim_3dgs(gt[..., 0], gt[..., 0]) == pytest.approx(1.0, abs=1e-12)
    assert abs(ssim_3dgs(pred, gt) - ssim(pred, gt)) > 0.01


def test_l2_loss_learns_the_mean_rate_where_l1_learns_the_median():
    """A flat scene firing 0.1 spikes/readout, 9-readout windows: the count is mostly 0 or 1, so
    the L1 optimum (a median, 0 or 1/9) misses the rate that the L2 optimum (the mean) finds."""
    stream = BernoulliStream(lambda k: np.full((20, 20), 0.1, np.float32), 80, seed=1)
    ks = valid_timestamps(stream, 9)
    fit = {"steps": 150, "batch_size": 4, "crop": 16, "progress": False, "lr": 1e-2}
    means = {
        loss: float(
            infer_sim(train_sim(stream, ks, 9, loss=loss, seed=0, **fit)[0], stream, ks).mean()
        )
        for loss in ("l1", "l2")
    }
    # Binomial(9, 0.1) counts: median 1 -> 1/9 = 0.111 (measured 0.1108); mean 0.1 (0.0982)
    assert abs(means["l2"] - 0.1) < 0.006, means
    assert abs(means["l1"] - 1 / 9) < 0.006 and means["l1"] - means["l2"] > 0.007, means
    with pytest.raises(ValueError, match="SIM loss"):
        train_sim(stream, ks, 9, loss="huber", **fit)
    with pytest.raises(ValueError, match="no training timestamps"):  # (not numpy's error)
        train_sim(stream, [], 9, **fit)


def test_centred_target_learns_the_light_at_t_not_the_window_mean():
    """Light flashes (0.6 spikes/readout) for the 9 readouts around each training timestamp and
    is dim (0.05) otherwise: against the whole 33-readout window SIM learns the window's mean
    (0.2, the motion blur of a moving camera in miniature); against its 9 centre readouts it
    learns the light at t."""
    period = 40
    stream = BernoulliStream(
        lambda k: np.full((20, 20), 0.6 if abs(k % period - 20) <= 4 else 0.05, np.float32),
        6 * period,
        seed=2,
    )
    ks = np.arange(20, len(stream) - 20, period)  # the flashes' centres
    fit = {"steps": 150, "batch_size": 4, "crop": 16, "progress": False, "lr": 1e-2, "seed": 0}
    learned = {
        target: float(
            infer_sim(train_sim(stream, ks, 33, target_window=target, **fit)[0], stream, ks).mean()
        )
        for target in (33, 9)
    }
    assert abs(learned[33] - (24 * 0.05 + 9 * 0.6) / 33) < 0.02, learned
    assert abs(learned[9] - 0.6) < 0.03, learned
    for bad in (0, 8, 35):
        with pytest.raises(ValueError, match="target window"):
            train_sim(stream, ks, 33, target_window=bad, **fit)


def test_bad_input_refused():
    net = SIM(window=9)
    for x in (torch.rand(9, 12, 20), torch.rand(1, 7, 12, 20)):  # no batch axis; wrong window
        for path in (net, net.forward_rotated):
            with pytest.raises(ValueError, match=r"expected \[B, 9, H, W\]"):
                path(x)
    with pytest.raises(ValueError, match="dtype torch.float32"):
        net(torch.rand(1, 9, 12, 20, dtype=torch.float64))
    for bad in ({"out_channels": 0}, {"window": 2.5}, {"width": -1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            SIM(**bad)
    with pytest.raises(ValueError, match="target window expected an int, found 17.0"):
        SIM(target_window=17.0)  # passed, then failed as a slice index in the first forward


def test_sim_train_cli_needs_an_on_path_view_before_training(tmp_path, monkeypatch, capsys):
    from spikegs.cli import main
    from spikegs.data import simulate_dataset

    root = tmp_path / "off"
    small = dict(height=16, width=16, readouts=200, test_on_path=0, test_off_path=1)
    simulate_dataset("solids", root, progress=False, **small)
    monkeypatch.setattr("spikegs.sim_cli.trained_sim", lambda *a, **k: pytest.fail("trained"))
    assert main(["sim-train", str(root)]) == 2
    assert "no held-out view on the camera path" in capsys.readouterr().err
    # a window longer than the room around the timestamps: refused by its flag, not mid-training
    assert main(["sim-train", str(root), "--window", "201"]) == 2
    assert "--window: config: sim.window = 201 readouts does not fit" in capsys.readouterr().err


def _view_moved(root, readout: float, first: int, last: int) -> None:
    """The dataset at `root` with its first on-path view moved to `readout` and its training
    timestamps in [first, last] (a real recording's view near its start)."""
    doc = json.loads((root / "test_views.json").read_text())
    next(f for f in doc["frames"] if f["readout"] is not None)["readout"] = readout
    (root / "test_views.json").write_text(json.dumps(doc))
    ts = np.loadtxt(root / "train_timestamps.txt", dtype=np.int64)
    np.savetxt(root / "train_timestamps.txt", ts[(ts >= first) & (ts <= last)], fmt="%d")


def test_sim_train_scores_the_views_whose_windows_fit_said_once(tmp_path, monkeypatch, capsys):
    """A view near the stream's start (a real recording's): left out of sim-train's scores,
    said once (the views found before training are scored); with SIM's window the widest,
    judged by it before training (--window 101: a view 45 readouts in)."""
    from spikegs.cli import main
    from spikegs.data import simulate_dataset

    root = tmp_path / "near"
    small = dict(height=16, width=16, readouts=600, test_on_path=2, test_off_path=0)
    simulate_dataset("solids", root, progress=False, **small)
    _view_moved(root, 20.0, 130, 540)
    assert main(["sim-train", str(root), "--steps", "2", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert err.count("left out of the scores: on_000 (readout 20)") == 1, err
    _view_moved(root, 45.0, 130, 540)

    def stopped(*args, **kwargs):  # (the warning comes before SIM's training)
        raise KeyboardInterrupt

    monkeypatch.setattr("spikegs.sim_cli.trained_sim", stopped)
    assert main(["sim-train", str(root), "--window", "101", "--no-progress"]) == 130
    err = capsys.readouterr().err
    assert "within 50 readouts of their stream's ends, where a 101-readout window" in err, err


def test_a_batch_that_cannot_fit_in_memory_is_refused_before_a_step(scene, monkeypatch):
    """`sim-train --batch-size 5000` was killed by the kernel at 24 GB, with no word: a step's
    memory, at least STEP_BYTES_PER_MAP a crop pixel and feature map, is checked first."""
    from spikegs import sim_train

    stream, ts = scene[1], valid_timestamps(scene[1], 33)
    maps = 33 + 32 * 3 + 32 * 3  # the window's, width per shift layer, head_width per head layer
    crop = min(stream.height, stream.width, 16)
    monkeypatch.setattr(sim_train, "machine_memory", lambda: 2**30)
    batch = 2**30 // (sim_train.STEP_BYTES_PER_MAP * maps * crop * crop) + 1
    monkeypatch.setattr(SIM, "forward_rotated", lambda *a, **k: pytest.fail("stepped"))
    said = rf"SIM batch {batch} of {crop}x{crop} crops: a training step needs over 1.0 GiB, more "
    said += r"than the 1.0 GiB this process may use; a smaller batch \(sim-train --batch-size"
    with pytest.raises(ValueError, match=said):
        train_sim(stream, ts, 33, steps=1, batch_size=batch, crop=crop, progress=False)
    # a wider network holds more maps a pixel: a third of that batch, 9 times as wide, is refused
    with pytest.raises(ValueError, match=f"SIM batch {batch // 3} of "):
        train_sim(
            stream, ts, 33, steps=1, batch_size=batch // 3, crop=crop, width=288, progress=False
        )


@pytest.mark.parametrize(
    "args, message",
    [
        (["--window", "4"], "--window: config: sim.window = 4"),
        (["--target-window", "35"], "sim.target_window = 35"),
        (["--out", "adir"], "--out adir: is a folder"),  # ('.' is refused while parsing)
        (["--out", "file/sim.pt"], "a folder on its path is a file"),
        # a dataset's spikes.dat named by mistake was trained over as an 'unreadable' cache
        (["--out", "file"], "--out file: an existing file that is not a saved SIM"),
        # --force ("retrain even if the weights exist") left it too, unsaid why (the sim-train
        # trial: a SIM's file cut short)
        # (a recording's spikes.dat named by mistake: "delete it" comes with its condition)
        (["--out", "file", "--force"], "not replace, --force or not; give another path (where"),
        # its scores were written over a dataset's test_views.json, which then read as "no
        # convention" (the sim-train trial)
        (["--out", "test_views"], "its scores go to test_views.json, an existing file that is no"),
    ],
)
def test_sim_train_cli_refuses_bad_options_before_training(
    args, message, tmp_path, monkeypatch, capsys
):
    """An --out that was a directory or under a file was found out after training (and a
    directory read as an 'unreadable' cache); an even --window was trained."""
    from spikegs.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "file").write_text("")
    (tmp_path / "adir").mkdir()
    (tmp_path / "test_views.json").write_text('{"convention": "opencv", "frames": []}')
    monkeypatch.setattr("spikegs.sim_cli.load_dataset", lambda *a: pytest.fail("loaded"))
    assert main(["sim-train", "data", *args]) == 2
    assert message in capsys.readouterr().err


def test_sim_train_writes_its_scores_before_printing_them(tmp_path, monkeypatch, capsys):
    """A stdout on a full disk (`> /dev/full`) stopped sim-train at its table, before the scores
    file beside the weights, which outputs.md promises (the environment trial)."""
    from spikegs.cli import main
    from spikegs.data import simulate_dataset

    root = tmp_path / "on"
    small = dict(height=16, width=16, readouts=200, test_on_path=1, test_off_path=0)
    simulate_dataset("solids", root, progress=False, **small)

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("spikegs.sim_cli.print_table", full)
    out = tmp_path / "sim.pt"
    args = ["sim-train", str(root), "--steps", "2", "--crop", "16", "--batch-size", "1"]
    assert main([*args, "--no-progress", "--out", str(out)]) == 2
    assert json.loads((tmp_path / "sim.pt.json").read_text())["sim"] == str(out.resolve())
    assert _is_scores_record(tmp_path / "sim.pt.json")  # (a later run writes over it)


def test_sim_train_cli_says_how_to_continue_after_ctrl_c(tmp_path, monkeypatch, capsys):
    """An interrupted `spikegs sim-train` printed only 'interrupted'."""
    from spikegs.cli import main
    from spikegs.data import simulate_dataset

    root = tmp_path / "on"
    small = dict(height=16, width=16, readouts=200, test_on_path=1, test_off_path=0)
    simulate_dataset("solids", root, progress=False, **small)
    calls = []

    def ctrl_c(*args, **kwargs):
        calls.append(kwargs["progress"])
        raise KeyboardInterrupt

    monkeypatch.setattr("spikegs.sim_cli.trained_sim", ctrl_c)
    assert main(["sim-train", str(root), "--no-progress"]) == 130
    assert calls == [False]
    said = capsys.readouterr().err  # (stopped before training: while waiting for a lock, say)
    assert "the same command (without --force) continues from SIM's last saved state, if" in said


@pytest.mark.parametrize("path", ["forward", "forward_rotated"])
def test_a_fresh_sim_outputs_zero_whatever_it_sees(path):
    """The output layer starts at zero, weights and bias (sim.py, BENCHMARKS.md "What decides a
    300-step SIM"): a fresh SIM's first output is exactly 0, in training too (no clamp there)."""
    torch.manual_seed(0)
    model = SIM(window=9).train()
    y = getattr(model, path)(_spikes(2, 9, 11, 13))
    assert y.shape == (2, 1, 11, 13)
    assert torch.equal(y, torch.zeros_like(y))


def _constant_features_sim() -> SIM:
    """window 1, width 1, one shift layer, two head layers of width 1: the shift convolution
    outputs its bias -1 everywhere (weights 0), the head sums the four branches (weights 1,
    bias 0), the output layer adds 1 (weight 1, bias 1)."""
    model = SIM(window=1, width=1, head_width=1, shift_layers=1, head_layers=2)
    with torch.no_grad():
        model.shift[0].weight.zero_()
        model.shift[0].bias.fill_(-1.0)
        model.head[0].weight.fill_(1.0)
        model.head[0].bias.zero_()
        model.head[1].weight.fill_(1.0)
        model.head[1].bias.fill_(1.0)
    return model


@pytest.mark.parametrize("path", ["forward", "forward_rotated"])
def test_the_activation_is_a_leaky_relu_of_slope_0_1(path):
    """Every branch reads leaky(-1) = -0.1 at a neighbour inside the image; an interior pixel sums
    its four branches, -0.4, the head's leaky ReLU makes it -0.04, the output 1 - 0.04 = 0.96.
    A corner pixel has two neighbours (the blind spot reads zeros past the image): 1 - 0.02.
    (A slope s gives 1 - 4 s^2: a saved SIM depends on it; a plain ReLU in the head gives 1.)"""
    model = _constant_features_sim().train()  # training: no clamp
    with torch.no_grad():
        y = getattr(model, path)(torch.zeros(1, 1, 5, 6))[0, 0]  # [5, 6]
    slope = 0.1
    torch.testing.assert_close(y[2, 3], torch.tensor(1 - 4 * slope * slope), rtol=0, atol=1e-6)
    torch.testing.assert_close(y[0, 0], torch.tensor(1 - 2 * slope * slope), rtol=0, atol=1e-6)


def test_inference_clamps_to_0_1_and_training_does_not():
    """Outside training the output is clamped to [0, 1] (firing rates); in training it is not
    (a saturating output dies under L1 on low rates, `SIM._merge`)."""
    model = SIM(window=3)
    x = _spikes(1, 3, 7, 8)
    for bias, clamped in ((1.5, 1.0), (-0.5, 0.0), (0.25, 0.25)):
        with torch.no_grad():
            model.head[-1].bias.fill_(bias)  # the weights are zero: the output is the bias
            assert torch.equal(model.train()(x), torch.full((1, 1, 7, 8), bias))
            assert torch.equal(model.eval()(x), torch.full((1, 1, 7, 8), clamped))
            assert torch.equal(model.forward_rotated(x), torch.full((1, 1, 7, 8), clamped))


class SpikeArray:
    """A stand-in spike stream held whole: Bernoulli spikes of `rate`, uint8 [T, H, W]."""

    def __init__(self, height: int, width: int, length: int, rate: float = 0.2, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.spikes = (rng.random((length, height, width)) < rate).astype(np.uint8)
        self.height, self.width = height, width

    def __len__(self) -> int:
        return len(self.spikes)

    def digest(self) -> bytes:
        return hashlib.sha256(self.spikes.tobytes()).digest()

    def window(self, k, w: int) -> np.ndarray:  # [w, H, W] ([B, w, H, W])
        one = lambda i: self.spikes[int(i) - w // 2 : int(i) - w // 2 + w]  # noqa: E731
        return np.stack([one(i) for i in k]) if np.ndim(k) else one(k)


TINY = dict(steps=2, batch_size=1, crop=16, progress=False)
W = 9  # the SIM window of these tests (a short one: fast)


def _ts(stream, w=W):
    lo, hi = centred_range(len(stream), w)
    return np.arange(lo, hi + 1)


def test_the_crop_warning_names_crops_under_the_field_that_miss_part_of_the_frame():
    """The warning is for a crop under the 15-pixel field that is smaller than the frame along a
    side (training sees a zero border where inference sees the frame), not for a crop as large
    as the frame: on an 8x14 frame crop 10 (8x10 crops) warns, crop 14 and crop 16 (the whole
    frame) do not, and a crop taller than the frame crops the full height."""
    stream = SpikeArray(8, 14, 30)
    ts = _ts(stream)
    with pytest.warns(UserWarning, match="SIM crop 10: under the 15-pixel square"):
        train_sim(stream, ts, W, steps=1, batch_size=2, crop=10, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for crop in (14, 16):
            model, losses = train_sim(
                stream, ts, W, steps=1, batch_size=2, crop=crop, progress=False
            )
            assert len(losses) == 1 and np.isfinite(losses[0])


def test_a_sim_cached_from_another_start_is_retrained(tmp_path, capsys):
    """A SIM cached with another `start` (trained before SIM started at zero) is not reused, with
    everything else the same: its data, window and settings."""
    stream = SpikeArray(12, 12, 40)
    path, ts = tmp_path / "sim.pt", [20, 21]
    assert train_or_load(path, stream, ts, W, **TINY)[1] > 0
    assert train_or_load(path, stream, ts, W, **TINY)[1] == 0  # the same: reused
    payload = torch.load(path, weights_only=True)
    payload["meta"]["start"] = "pytorch-default"
    torch.save(payload, path)
    capsys.readouterr()
    assert train_or_load(path, stream, ts, W, **TINY)[1] > 0
    assert "from another start; training SIM afresh" in capsys.readouterr().err


def test_no_user_cache_is_looked_in_where_there_is_none(tmp_path, monkeypatch):
    """No home directory (no user cache): a SIM trains in a writable folder; a file the user
    named, holding a SIM of other spikes, is refused as such."""
    monkeypatch.setattr(sim_train, "cache_home", lambda: None)
    path, stream = tmp_path / "sim.pt", SpikeArray(12, 12, 40)
    assert train_or_load(path, stream, [20, 21], W, **TINY)[1] > 0
    with pytest.raises(FileExistsError, match=f"{path}: a SIM trained on other spikes, for anoth"):
        train_or_load(path, stream, [22, 23], W, keep=True, **TINY)


def test_a_user_cache_that_cannot_be_read_is_no_cache(tmp_path, monkeypatch):
    """The lookup of a SIM stranded in the user cache, on a writable dataset: a cache that
    cannot be read (a container's user with HOME=/root) raised PermissionError where SIM had
    trained before (the review)."""
    unreadable = Path("/proc/1/root/spikegs-cache")
    try:
        unreadable.exists()
        pytest.skip("no path that refuses to be read here")  # (root outside a container, macOS)
    except PermissionError:
        pass
    monkeypatch.setenv("XDG_CACHE_HOME", str(unreadable))
    assert train_or_load(tmp_path / "sim.pt", SpikeArray(12, 12, 40), [20, 21], W, **TINY)[1] > 0


@pytest.mark.parametrize("name, what", [("sim.pt", "weights"), ("sim.pt.json", "scores")])
def test_a_folder_where_a_sim_is_saved_is_refused_before_training(
    tmp_path, monkeypatch, name, what
):
    """A folder at a cache's path, the weights' or their scores record's: SIM trained, then its
    save ended the command ("[Errno 21] Is a directory"), the training lost (the sim-train
    trial)."""
    monkeypatch.setattr(sim_train, "train_sim", lambda *a, **k: pytest.fail("trained"))
    (tmp_path / name).mkdir()
    said = f"{tmp_path / name}: a folder where SIM's {what} are saved, .*; move or delete it"
    with pytest.raises(IsADirectoryError, match=said):
        train_or_load(tmp_path / "sim.pt", SpikeArray(12, 12, 40), [20, 21], W, **TINY)


def test_progress_is_not_a_setting_of_a_cached_sim(tmp_path):
    """A SIM trained with a progress bar is the one trained without: `spikegs sim-train` then
    `spikegs train --no-progress` reuse it (progress is not in its meta)."""
    stream = SpikeArray(12, 12, 40)
    path, ts = tmp_path / "sim.pt", [20, 21]
    assert train_or_load(path, stream, ts, W, **{**TINY, "progress": False})[1] > 0
    assert "progress" not in torch.load(path, weights_only=True)["meta"]
    assert train_or_load(path, stream, ts, W, **{**TINY, "progress": True})[1] == 0


def test_a_sim_saved_with_the_crop_asked_for_is_reused(tmp_path, capsys):
    """SIMs saved before 2026-11-25 recorded the crop asked for (64), which training took at
    most the frames' larger side (12): called 'trained with other settings', retrained bit for
    bit and overwritten."""
    stream = SpikeArray(12, 12, 40)
    path, ts = tmp_path / "sim.pt", [20, 21]
    assert train_or_load(path, stream, ts, W, **TINY)[1] > 0
    payload = torch.load(path, weights_only=True)
    payload["meta"]["crop"] = 64
    torch.save(payload, path)
    assert train_or_load(path, stream, ts, W, **TINY)[1] == 0
    assert "other settings" not in capsys.readouterr().err


def test_user_cache_folder_is_the_fingerprints_first_16_hex_digits(tmp_path, monkeypatch):
    """SIMs cached in the user cache lie under spikegs/sim/<16 hex digits>/: where earlier SIMs
    were saved, and found again (a longer name would retrain each of them)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    digest = hashlib.sha256(b"spikes").hexdigest()  # 64 hex digits, as spikes_fingerprint's
    assert user_cache("sim.pt", digest) == tmp_path / "spikegs" / "sim" / digest[:16] / "sim.pt"


def _read_only(monkeypatch, tmp_path) -> Path:
    """A dataset's sim folder that cannot be written (as test_sim.py's read-only test), and a
    user cache in tmp_path."""
    dataset_sim = tmp_path / "dataset" / "sim"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(
        "spikegs.sim_train.writable_folder",
        lambda folder: Path(folder) != dataset_sim and writable_folder(folder),
    )
    return dataset_sim / "sim.pt"


def test_force_retrains_a_sim_cached_in_the_users_cache(tmp_path, monkeypatch):
    """--force retrains a read-only dataset's SIM too (it is cached in the user's cache), and
    saves it where it was found."""
    path = _read_only(monkeypatch, tmp_path)
    stream, ts = SpikeArray(12, 12, 40), [20, 21]
    _, seconds, cached = train_or_load(path, stream, ts, W, **TINY)
    assert seconds > 0 and cached.is_relative_to(tmp_path / "cache")
    assert train_or_load(path, stream, ts, W, **TINY)[1:] == (0, cached)
    _, seconds, again = train_or_load(path, stream, ts, W, force=True, **TINY)
    assert seconds > 0 and again == cached


def test_force_trains_afresh_instead_of_resuming(tmp_path, monkeypatch, capsys):
    """--force does not resume an interrupted training's state: it trains from step 0, to the
    SIM of a training never interrupted."""
    monkeypatch.setattr("spikegs.sim_train.CHECKPOINT_S", 0.0)  # state saved every step
    stream, path = SpikeArray(12, 12, 40), tmp_path / "sim.pt"
    ts, settings = _ts(stream), dict(steps=4, batch_size=1, crop=12, progress=False, seed=1)
    with pytest.raises(KeyboardInterrupt):
        train_or_load(path, _CtrlC(stream, at=3), ts, W, **settings)
    assert torch.load(path.with_name("sim.pt.partial"), weights_only=True)["step"] == 2
    capsys.readouterr()
    forced, _, _ = train_or_load(path, stream, ts, W, force=True, **settings)
    assert "resumes" not in capsys.readouterr().err
    fresh, _ = train_sim(stream, ts, W, **settings)
    for a, b in zip(forced.state_dict().values(), fresh.state_dict().values()):
        assert torch.equal(a, b)


def test_a_torn_training_state_is_said_and_trained_over(tmp_path, capsys):
    """A sim.pt.partial that cannot be read (a disk that filled while it was saved): said, and
    SIM trained from step 0, to the SIM of a training never interrupted."""
    stream, path = SpikeArray(12, 12, 40), tmp_path / "sim.pt"
    ts, settings = _ts(stream), dict(steps=2, batch_size=1, crop=12, progress=False, seed=1)
    assert sim_train._resumable(path.with_name("sim.pt.partial"), {}) is None  # none: no news
    assert capsys.readouterr().err == ""
    path.with_name("sim.pt.partial").write_bytes(b"half")
    torn, _, _ = train_or_load(path, stream, ts, W, **settings)
    assert "sim.pt.partial: unreadable (" in capsys.readouterr().err
    # another file: torch's advice to load it with weights_only=False (which runs its code) was
    # passed on (the sim-train trial)
    (tmp_path / "other.partial").write_bytes(b"garbage\n")
    assert sim_train._resumable(tmp_path / "other.partial", {}) is None
    err = capsys.readouterr().err
    assert "other.partial: unreadable (UnpicklingError: torn, or not" in err
    assert "weights_only" not in err
    fresh, _ = train_sim(stream, ts, W, **settings)
    for a, b in zip(torn.state_dict().values(), fresh.state_dict().values()):
        assert torch.equal(a, b)


def test_a_resumed_trainings_earlier_seconds_are_saved_again(tmp_path, monkeypatch):
    """Interrupted twice, the second state saved holds the seconds of the first process too
    (the SIM's recorded training time counts every process's steps)."""
    monkeypatch.setattr("spikegs.sim_train.CHECKPOINT_S", 0.0)
    stream, path = SpikeArray(12, 12, 40), tmp_path / "sim.pt"
    ts, settings = _ts(stream), dict(steps=6, batch_size=1, crop=12, progress=False)
    partial = path.with_name("sim.pt.partial")
    with pytest.raises(KeyboardInterrupt):
        train_or_load(path, _CtrlC(stream, at=2), ts, W, **settings)
    state = torch.load(partial, weights_only=True)
    state["seconds"] = 1000.0  # as if the first process trained for 1000 s
    torch.save(state, partial)
    with pytest.raises(KeyboardInterrupt):
        train_or_load(path, _CtrlC(stream, at=3), ts, W, **settings)
    state = torch.load(partial, weights_only=True)
    assert state["step"] == 3 and 1000.0 <= state["seconds"] < 1100.0


def test_a_colour_sim_trains_on_crops_of_every_channel():
    """With a list of streams (a colour camera's channels) each crop comes from a random one of
    them: 24 crops of 2 channels all from the first has probability 2^-24."""
    channels = [_CtrlC(SpikeArray(12, 12, 40, seed=c), at=None) for c in range(2)]
    train_sim(channels, _ts(channels[0]), W, steps=6, batch_size=4, crop=12, progress=False)
    assert sum(c.calls for c in channels) == 24 and all(c.calls > 0 for c in channels)


def test_fast_inference_is_bfloat16_only_where_the_cpu_has_it(monkeypatch):
    """bfloat16 where the CPU computes it natively, float32 elsewhere (an emulated bfloat16 is
    slower); a dtype given is kept."""
    model = SIM(window=W)
    for native, dtype in ((True, torch.bfloat16), (False, torch.float32)):
        monkeypatch.setattr(sim_train, "bf16_is_fast", lambda native=native: native)
        assert next(fast_inference_model(model).parameters()).dtype == dtype
        assert next(fast_inference_model(model, torch.float64).parameters()).dtype == torch.float64


def test_bf16_is_native_with_either_flag_in_cpuinfo(monkeypatch):
    """AVX-512 BF16 or AMX (either flag in /proc/cpuinfo) computes bfloat16 natively; neither,
    or no /proc/cpuinfo to read (macOS, Windows), does not."""
    read_text = Path.read_text
    cases = (("avx512f avx512_bf16", True), ("amx_bf16 amx_tile", True), ("avx2 fma", False))
    for flags, native in (*cases, (None, False)):

        def cpuinfo(path, *args, flags=flags, **kwargs):
            if str(path) != "/proc/cpuinfo":
                return read_text(path, *args, **kwargs)
            if flags is None:
                raise FileNotFoundError(path)
            return f"flags\t\t: {flags}\n"

        monkeypatch.setattr(Path, "read_text", cpuinfo)
        assert sim_train.bf16_is_fast.__wrapped__() == native, flags


def test_the_bar_shows_the_mean_loss_of_the_last_50_steps_every_50():
    """A step a tick; every 50th, the mean of the last 50 losses beside the bar."""

    class Bar:
        def __init__(self):
            self.n, self.shown = 0, []

        def update(self, n):
            self.n += n

        def set_postfix(self, loss):
            self.shown.append((self.n, loss))

    bar, losses = Bar(), []
    for step in range(120):
        losses.append(float(step))
        sim_train._show_step(bar, losses)
    assert bar.n == 120 and bar.shown == [(49, "24.5000"), (99, "74.5000")]


def test_recorded_seconds_are_positive_numbers_or_zero(tmp_path):
    """A saved SIM's training seconds count towards a run's time only as a positive number."""
    model, path = SIM(window=W), tmp_path / "sim.pt"
    for seconds, recorded in ((12.5, 12.5), (-3.0, 0.0), (0.0, 0.0), ("12", 0.0)):
        save_sim(model, path, seconds=seconds)
        assert recorded_seconds(path) == recorded, seconds
    save_sim(model, path)  # none recorded
    assert recorded_seconds(path) == 0.0
    path.write_bytes(b"not a SIM")
    assert recorded_seconds(path) == 0.0


def test_loading_a_sim_leaves_torch_global_generator(tmp_path):
    """A SIM loaded (or copied for inference) drew its discarded default init from torch's global
    generator: a script's sweep of `Trainer`s (README) got other random numbers after each."""
    model = SIM(window=9, target_window=9)
    save_sim(model, tmp_path / "sim.pt")
    torch.manual_seed(0)
    state = torch.get_rng_state()
    loaded = load_sim(tmp_path / "sim.pt")
    sim_train.inference_model(loaded)
    assert torch.equal(torch.get_rng_state(), state)


def test_training_crops_reach_every_edge_of_the_frame(monkeypatch):
    """Crops of 7 on an 8×8 frame start at row and column 0 or 1, each: spikes on the last row
    and column alone, some crops hold each (offsets to height - crop exclusive never trained on
    the frame's last row, and passed every test)."""
    bits = np.zeros((10, 8, 8), bool)
    bits[:, -1, :3] = True  # the last row, away from the last column
    bits[:, :3, -1] = True  # the last column, away from the last row
    seen = []
    to_input = sim_train._to_input
    monkeypatch.setattr(
        sim_train, "_to_input", lambda crops, *a: seen.append(crops) or to_input(crops, *a)
    )
    stream = SpikeStream.from_bits(bits)
    train_sim(stream, [4, 5], 3, steps=8, batch_size=4, crop=7, shift_layers=1, progress=False)
    crops = np.concatenate(seen)  # [32, 3, 7, 7]
    assert crops.shape == (32, 3, 7, 7)
    assert crops[:, :, -1, :].any() and crops[:, :, :, -1].any()


def test_the_api_refuses_what_would_fail_later_by_name():
    """train_sim's crop, batch or steps under 1 failed in torch or numpy at the first step, a
    timestamp whose window runs past the stream at the first step to draw it (minutes in);
    infer_sim of no timestamps in np.concatenate; a SIM given numpy's integers refused them."""
    stream = SpikeStream.from_bits(np.random.default_rng(0).random((100, 12, 12)) < 0.3)
    for setting in ({"crop": 0}, {"batch_size": 0}, {"steps": 0}):
        (name,) = setting
        with pytest.raises(ValueError, match=f"SIM {name} expected a positive int, found 0"):
            train_sim(stream, [50], 33, progress=False, **setting)
    with pytest.raises(ValueError, match=r"timestamps \[5, 99\]: .* \(centres 16..83 fit\)"):
        train_sim(stream, [5, 50, 99], 33, steps=1, progress=False)
    with pytest.raises(ValueError, match="of 101 readouts .* 100 readouts .longer than the stream"):
        train_sim(stream, [50], 101, steps=1, progress=False)  # (said "centres 50..49 fit")
    # numpy's "all input arrays must have the same shape" at the first step, for either
    with pytest.raises(ValueError, match=r"1-D integer array, found int64 of shape \(1, 2\)"):
        train_sim(stream, [[40, 50]], 33, steps=1, progress=False)
    narrow = SpikeStream.from_bits(np.zeros((100, 12, 10), bool))  # (first, its crops drew
    with pytest.raises(ValueError, match=r"differ in frame size: \['12x10', '12x12'\]"):
        train_sim([narrow, stream], [50], 33, steps=1, progress=False)  # the other's rows)
    # a notebook's torch.no_grad() left around the call: trained (torch's error at the step);
    # under inference_mode, no tensor takes a gradient: refused by name
    with torch.inference_mode(), pytest.raises(RuntimeError, match="train_sim: called under"):
        train_sim(stream, [50], 33, steps=1, crop=12, progress=False)
    with torch.no_grad():
        model, _ = train_sim(stream, [50], 33, steps=1, crop=12, progress=False)
    assert infer_sim(model, stream, []).shape == (0, 12, 12, 1)
    # one readout alone: "len() of unsized object"; a batch of 0: "range() arg 3 must not be zero"
    np.testing.assert_array_equal(infer_sim(model, stream, 50), infer_sim(model, stream, [50])[0])
    with pytest.raises(ValueError, match="SIM batch_size expected a positive int, found 0"):
        infer_sim(model, stream, [50], batch_size=0)
    assert SIM(window=np.int64(5)).config["window"] == 5
    with pytest.raises(ValueError, match=r"SIM input expected \[B, 5, H, W\], H, W ≥ 1"):
        SIM(window=5)(torch.zeros(2, 5, 0, 7))
