"""Packed spike streams: lazy access, window counts, TFP and TFI from the C++ core, .dat writing.

In memory a stream stays packed, `[T, H, ceil(W/8)]` uint8, least significant bit first, row 0 at
the top. A `.dat` file is the spike camera's layout: frames of H·W/8 bytes (rounded up to whole
bytes when H·W is not a multiple of 8), row-major and bit-contiguous, rows stored bottom-up when
`flip` (the readers of this family flip on load). Decoding happens on the fly, window by window.

TFP(k, w): mean of the spikes in the w readouts k - w//2 .. k - w//2 + w - 1.
TFI(k) = 1 / min(t_next - t_prev, max_interval): t_prev is the last readout <= k with a spike (a
spike at k, or at readout 0, counts), t_next the first readout > k with one, and a side with no
spike is infinitely far. A pixel with no spike pair within max_interval, and every pixel at the
last readout, reads 1/max_interval: never inf or NaN.

Times, where readout k reads the light at time k (the simulator's convention, pose_at(k)): TFP(k,
w) shows the light at k for odd w and at k - 1/2 for even w (the middle of its readouts); TFI(k)
at k + 1/2 (its interval always straddles readouts k and k + 1).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import uuid
import warnings
from pathlib import Path

import numpy as np

from .. import _C
from ..atomic_save import naming, temporary_name, written_path
from ..cache_home import CACHED_FROM, cache_home, write_cached
from ..number_checks import as_flag, holds_bool, is_int, is_number, whole_numbers
from ..shell_words import shell_path

PathLike = str | os.PathLike
TFI_DEFAULT_MAX_INTERVAL: int = _C.TFI_DEFAULT_MAX_INTERVAL


def _whole(value) -> bool:
    """Whether `value` is a whole number (an int, or a float such as 33.0, or a 0-d array or
    tensor of one, as readout indices may be; not inf, NaN, None or a bool)."""
    if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):
        value = value.item()
    return is_int(value) or (is_number(value) and float(value).is_integer())


def as_readouts(k) -> tuple[np.ndarray, bool]:
    """`k` as a 1-D int64 array [B], and whether it was a single index; whole-number floats
    (a readout time such as `TestView.readout`) are accepted."""
    if holds_bool(k):  # np.asarray read [4, True] as readouts 4 and 1
        raise ValueError(f"readout index expected an int or a 1-D integer array, found {k!r}")
    arr = np.asarray(k)
    # uint64 against uint64: against a Python int numpy < 1.25 compared in float64 (2^63 passed)
    if arr.dtype.kind == "u" and arr.size and arr.max() > np.uint64(np.iinfo(np.int64).max):
        raise ValueError(f"readout index expected below 2^63, found {arr.max()}")
    if np.issubdtype(arr.dtype, np.floating):
        arr = arr.astype(np.float64)  # (float16 cannot hold the bound: numpy warned)
        if np.all(np.abs(arr) < 2.0**62) and np.all(arr == np.round(arr)):  # NaN: False
            arr = arr.astype(np.int64)
    if arr.ndim > 1 or not (arr.size == 0 or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(
            f"readout index expected an int or a 1-D integer array, found {arr.dtype} "
            f"of shape {arr.shape}" + (f" ({arr.tolist()})" if arr.size < 5 else "")
        )
    return arr.astype(np.int64).reshape(-1), arr.ndim == 0


def centred_range(length: int, w: int) -> tuple[int, int]:
    """[lo, hi]: the readouts k whose window of `w` (k - w//2 .. k - w//2 + w - 1) lies in a
    stream of `length` readouts."""
    return w // 2, length - w + w // 2


def _frame_count(num_bytes: int, layout: _C.SpikeLayout, path: Path | None) -> int:
    """Readouts in `num_bytes` bytes (of the file at `path`, or in memory); ValueError unless a
    whole number of frames."""
    fb = layout.frame_bytes
    if num_bytes % fb:
        whole, over = divmod(num_bytes, fb)
        cut = (  # a recording cut off mid-frame, not a wrong frame size: many frames, one part
            f"; a recording cut off mid-frame keeps its {whole} whole frames truncated to "
            f"{whole * fb} bytes (on a copy: `truncate -s {whole * fb} "
            f"{shell_path(path)}` deletes the rest)"
            if path is not None and whole >= 16
            else ""
        )
        raise ValueError(  # the size first: the likelier cause, and truncating loses data
            f"{path or 'packed data'}: a whole number of {layout.height}x{layout.row_bits}-bit "
            f"frames of {fb} bytes expected, found {num_bytes} bytes ({whole} frames and {over} "
            f"bytes over: is the frame size, height, width or raw_width, right?{cut})"
        )
    return num_bytes // fb


_DIGEST_CHUNK_BYTES = 64 << 20  # readouts hashed at a time by SpikeStream.digest
# a digest of more bytes is said on stderr as it is made: ~1 s for 1.2 GB in memory or in the
# page cache (250x400 x 96,000 readouts), a file from a disk longer
SAID_OVER = 1 << 30
MAX_WINDOW = _C.MAX_WINDOW  # the core counts spikes in int32


class SpikeStream:
    """A packed spike stream [T, H, W], memory-mapped or in memory, decoded window by window."""

    def __init__(self, data: np.ndarray, layout: _C.SpikeLayout, path: Path | None = None):
        if data.dtype != np.uint8 or not data.flags.c_contiguous:
            order = "C-contiguous" if data.flags.c_contiguous else "not C-contiguous"
            raise ValueError(
                f"packed data expected C-contiguous uint8, found {data.dtype}, {order}"
            )
        self._data = data  # uint8 bytes of T frames of layout.frame_bytes
        self._layout = layout
        self._len = _frame_count(data.size, layout, path)
        self.path = path
        self._digest: tuple | None = None  # (the file's identity when read, its digest)
        self._opened: tuple | None = None  # (absolute path, the file's identity) at `open`

    @classmethod
    def open(
        cls,
        path: PathLike,
        height: int,
        width: int,
        flip: bool = True,
        raw_width: int | None = None,
        col_offset: int = 0,
    ) -> SpikeStream:
        """Memory-map a .dat file; `raw_width` stored pixels per row, of which columns
        [col_offset, col_offset + width) are kept (raw camera files with extra columns)."""
        path = Path(path)
        raw = 0 if raw_width is None else raw_width  # 0: the core's "raw_width = width"
        try:  # (the file named: the sizes come from a dataset's files)
            height, width, raw, col_offset = whole_numbers(
                height=height, width=width, raw_width=raw, col_offset=col_offset
            )
            if raw_width is not None and raw < 1:
                raise ValueError(f"raw_width expected a positive int or None, found {raw_width!r}")
            layout = _C.SpikeLayout.dat(height, width, as_flag("flip", flip), raw, col_offset)
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from None
        if path.is_dir():  # its size was read as a cut-off recording's, to truncate
            raise IsADirectoryError(f"{path}: a folder, not a spike .dat file")
        size = path.stat().st_size
        _frame_count(size, layout, path)
        data = np.memmap(path, dtype=np.uint8, mode="r") if size else np.zeros(0, np.uint8)
        stream = cls(data, layout, path)
        absolute = path.resolve()  # (a later chdir does not move it)
        stream._opened = (absolute, _file_identity(absolute))
        return stream

    @classmethod
    def from_packed(
        cls, packed: np.ndarray, height: int | None = None, width: int | None = None
    ) -> SpikeStream:
        """Wrap packed [T, H, ceil(W/8)] uint8 (LSB first, row 0 on top; height: H by default),
        sharing its memory where it is C-contiguous (edits of the array after show in the
        stream); another layout (a strided slice, a transpose) is copied first.
        `width` is required: a row of B bytes holds 8B - 7 to 8B columns (a guess of 8B gave
        `simulate_spikes`' 13-wide frames 3 columns that never fire)."""
        packed = np.asarray(packed)
        if packed.ndim != 3 or packed.dtype != np.uint8:
            raise ValueError(
                f"packed expected uint8 [T, H, ceil(W/8)], found {packed.dtype} {packed.shape}"
            )
        if width is None:
            b = packed.shape[2]
            raise ValueError(
                f"from_packed needs width=: rows of {b} bytes hold {max(1, 8 * b - 7)} to {8 * b} "
                f"columns"
            )
        height = packed.shape[1] if height is None else height
        height, width = whole_numbers(height=height, width=width)
        if packed.shape[1:] != (height, (width + 7) // 8):
            raise ValueError(
                f"packed expected [T, {height}, {(width + 7) // 8}] for {height}x{width} frames, "
                f"found {list(packed.shape)}"
            )
        return cls(np.ascontiguousarray(packed), _C.SpikeLayout.memory(height, width))

    @classmethod
    def from_bits(cls, bits: np.ndarray) -> SpikeStream:
        """An in-memory stream of bits [T, H, W] (bool or 0/1 integers; row 0 on top), packed."""
        bits = _readouts_of(bits)
        _check_bits(bits)
        layout = _C.SpikeLayout.memory(bits.shape[1], bits.shape[2])
        return cls(_C.spike_pack(bits, layout), layout)

    def __reduce__(self):
        """Pickled (spawned workers, copy.deepcopy): a stream opened from a file is opened there
        again, by its path (its memory map pickled whole was the file's bytes, and a
        SpikeLayout no pickle at all); one in memory carries its bytes."""
        lay = self._layout
        layout = (lay.height, lay.width, lay.flip, lay.row_bits, lay.col_offset)
        if self._opened is not None:
            return _reopened, (*self._opened, layout)
        return _from_bytes, (np.asarray(self._data), layout, self.path)

    def __len__(self) -> int:
        return self._len

    @property
    def height(self) -> int:
        return self._layout.height

    @property
    def width(self) -> int:
        return self._layout.width

    @property
    def layout(self) -> _C.SpikeLayout:
        return self._layout

    def __repr__(self) -> str:
        where = f"'{self.path}'" if self.path else "memory"
        return (
            f"SpikeStream({where}, readouts={len(self)}, height={self.height}, width={self.width})"
        )

    def _starts(self, k, w: int) -> tuple[np.ndarray, bool]:
        """First readout [B] of the window of `w` centred on each k; ValueError past either end."""
        ks, single = as_readouts(k)
        if not _whole(w) or not 1 <= w <= MAX_WINDOW:
            raise ValueError(f"window length expected an int in 1..{MAX_WINDOW}, found {w!r}")
        w = int(w)
        lo, hi = centred_range(len(self), w)  # compared before any arithmetic on k (overflow)
        if lo > hi:
            raise ValueError(
                f"window of {w} readouts: longer than the stream's {len(self)} readouts"
            )
        bad = np.flatnonzero((ks < lo) | (ks > hi))
        if bad.size:
            k = int(ks[bad[0]])
            raise ValueError(
                f"window of {w} readouts centred on k={k} covers [{k - lo}, {k - lo + w}); "
                f"expected within the stream's [0, {len(self)}), i.e. k in [{lo}, {hi}]"
            )
        return ks - lo, single

    def window(self, k, w: int) -> np.ndarray:
        """Spikes, 0/1 uint8 [w, H, W], of readouts k - w//2 .. k - w//2 + w - 1 ([B, w, H, W])."""
        starts, single = self._starts(k, w)
        out = np.empty((len(starts), int(w), self.height, self.width), np.uint8)
        for i, s in enumerate(starts):
            out[i] = _C.spike_unpack(self._data, self._layout, int(s), int(w))
        return out[0] if single else out

    def counts(self, k, w: int) -> np.ndarray:
        """Spikes per pixel in the window of `w` centred on k: int32 [H, W] ([B, H, W])."""
        starts, single = self._starts(k, w)
        out = _C.spike_counts(self._data, self._layout, starts, int(w))
        return out[0] if single else out

    def tfp(self, k, w: int) -> np.ndarray:
        """Texture from playback: counts / w, float32 [H, W] ([B, H, W])."""
        starts, single = self._starts(k, w)
        out = _C.spike_tfp(self._data, self._layout, starts, int(w))
        return out[0] if single else out

    def tfi(self, k, max_interval: int = TFI_DEFAULT_MAX_INTERVAL) -> np.ndarray:
        """Texture from inter-spike interval (module docstring): float32 [H, W] ([B, H, W])."""
        ks, single = as_readouts(k)
        bad = np.flatnonzero((ks < 0) | (ks >= len(self)))
        if bad.size:
            raise ValueError(f"readout expected in [0, {len(self)}), found k={ks[bad[0]]}")
        bound = _C.TFI_MAX_INTERVAL  # the core's
        if not _whole(max_interval) or not 1 <= max_interval <= bound:
            found = f"found {max_interval!r}"
            raise ValueError(f"max_interval expected an int in [1, {bound}], {found}")
        out = _C.spike_tfi(self._data, self._layout, ks, int(max_interval))
        return out[0] if single else out

    def digest(self) -> bytes:
        """SHA-256 of the size and every readout, in the memory layout (the same spikes give the
        same digest from any file layout); read in chunks of ~64 MiB, ~0.1 s a 100 MB here. A
        file's is read once while the file is unchanged (its path, size, mtime and inode): kept by
        the stream (a command asks two or three times) and, for a file of CACHED_FROM bytes or
        more that is still the one mapped at `open`, in the user's cache for the next command (a
        10 GB recording took ~7 s each); one of over SAID_OVER bytes is said on stderr."""
        now = _file_identity(self._opened[0]) if self._opened else None  # the file as it is now
        if now is not None and self._digest is not None and self._digest[0] == now:
            return self._digest[1]
        nbytes = len(self) * self._layout.frame_bytes
        lay = self._layout  # the same bytes read in another layout are other spikes
        unchanged = now is not None and now == self._opened[1]  # still the file mapped at open
        key = f"{now}|{lay.height}x{lay.width}|{lay.flip}|{lay.row_bits}|{lay.col_offset}"
        cached = _digest_cache(key) if unchanged and nbytes >= CACHED_FROM else None
        digest = _read_digest(cached)
        if digest is None:
            if nbytes > SAID_OVER:  # (spikes in memory have no file to read)
                size, frame = f"{nbytes / 1e9:.1f} GB", f"{self.height}x{self.width}"
                said = (
                    f"{self.path}: reading {size} for its digest"
                    if self.path
                    else f"spikes in memory ({len(self)} readouts of {frame}): hashing {size} for "
                    f"their digest"
                )
                print(said, file=sys.stderr)
            sha = hashlib.sha256(np.asarray([len(self), self.height, self.width], np.int64).data)
            chunk = max(1, _DIGEST_CHUNK_BYTES // (self.height * ((self.width + 7) // 8)))
            for start in range(0, len(self), chunk):
                sha.update(self.packed(start, min(start + chunk, len(self))).data)
            digest = sha.digest()
            if cached is not None and _file_identity(self._opened[0]) == now:  # unchanged since
                _write_digest(cached, digest)
        self._digest = None if now is None else (now, digest)
        return digest

    def packed(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Readouts [start, stop) in the memory layout: uint8 [n, H, ceil(W/8)]; whole-number
        floats are accepted, as readouts everywhere (a window's, a view's)."""
        bounds = {"start": start, "stop": len(self) if stop is None else stop}
        start, stop = whole_numbers(**{k: int(v) if _whole(v) else v for k, v in bounds.items()})
        if not 0 <= start <= stop <= len(self):
            raise ValueError(f"readouts [{start}, {stop}) expected within [0, {len(self)})")
        mem = _C.SpikeLayout.memory(self.height, self.width)
        out = _C.spike_repack(self._data, self._layout, start, stop - start, mem)
        return out.reshape(stop - start, self.height, (self.width + 7) // 8)


def _reopened(path: Path, identity: str | None, layout: tuple) -> SpikeStream:
    """A pickled stream's file opened again (`SpikeStream.__reduce__`); ValueError where it is
    no longer the file that was opened (replaced, grown or cut since: other spikes)."""
    if _file_identity(path) != identity:
        raise ValueError(
            f"{path}: changed since a SpikeStream opened it (pickled for another process): open "
            f"it again"
        )
    height, width, flip, row_bits, col_offset = layout
    return SpikeStream.open(path, height, width, flip, row_bits, col_offset)


def _from_bytes(data: np.ndarray, layout: tuple, path: Path | None) -> SpikeStream:
    """A pickled in-memory stream (`SpikeStream.__reduce__`)."""
    return SpikeStream(data, _C.SpikeLayout.dat(*layout), path)


def _file_identity(path: Path) -> str | None:
    """The file at absolute `path` as its metadata tell it: path, size, mtime, inode, device
    (None where it is gone or unreadable)."""
    try:
        st = path.stat()
    except OSError:
        return None
    return f"{path}|{st.st_size}|{st.st_mtime_ns}|{st.st_ino}|{st.st_dev}"


def _digest_cache(key: str) -> Path | None:
    """The user-cache file holding the digest of the file `key` names (None: no cache folder)."""
    home = cache_home()
    name = hashlib.sha256(key.encode()).hexdigest()[:32]
    return None if home is None else home / "digests" / name


def _read_digest(path: Path | None) -> bytes | None:
    """The digest cached at `path`; None where there is none, or no readable one."""
    try:
        digest = bytes.fromhex(path.read_text()) if path is not None else None
    except (OSError, ValueError):
        return None
    return digest if digest is not None and len(digest) == hashlib.sha256().digest_size else None


def _write_digest(path: Path, digest: bytes) -> None:
    """Cache `digest` at `path`, where the cache folder can be written (else nothing: the next
    command reads the file again)."""
    write_cached(path, digest.hex())


def _readouts_of(bits) -> np.ndarray:
    """`bits` as an array of readouts [T, H, W]; ValueError for another number of dimensions, or
    for what is no array (a SpikeStream: `.window` or `.tfp` reads its readouts)."""
    given = bits
    bits = np.asarray(bits)
    if bits.ndim == 0 and bits.dtype == object:  # (np.asarray wrapped it: "found shape []")
        raise ValueError(f"bits expected an array [T, H, W], found a {type(given).__name__}")
    if bits.ndim != 3:
        raise ValueError(f"bits expected [T, H, W], found shape {list(bits.shape)}")
    return bits


def _check_bits(bits: np.ndarray) -> None:
    """ValueError unless `bits` are bool or integers 0/1."""
    if bits.dtype != np.bool_:
        if not np.issubdtype(bits.dtype, np.integer):
            raise ValueError(f"bits expected bool or 0/1 integers, found {bits.dtype}")
        if bits.size and (bits.min() < 0 or bits.max() > 1):
            raise ValueError(f"bits expected 0/1, found values in [{bits.min()}, {bits.max()}]")


class DatWriter:
    """Appends readouts to a .dat file, chunk by chunk (a context manager).

    The readouts go to a hidden file beside `path`, which replaces `path` when the writer closes:
    a stream still open on an earlier file there keeps reading it (truncating a memory-mapped file
    in place crashed its reader with SIGBUS), and writing that fails (an exception in the `with`
    block, or `discard`) leaves the earlier file, or none, rather than a truncated one."""

    def __init__(self, path: PathLike, height: int, width: int, flip: bool = True):
        self.path = Path(path)
        height, width = whole_numbers(height=height, width=width)
        self._layout = _C.SpikeLayout.dat(height, width, as_flag("flip", flip))
        self._memory = _C.SpikeLayout.memory(height, width)
        self._target = written_path(self.path)  # a symlink's target, not the link
        if self._target.is_dir():
            raise IsADirectoryError(f"{self.path}: a folder, not a .dat file to write")
        self._partial = self._target.with_name(temporary_name(self._target, uuid.uuid4().hex))
        try:
            self._file = open(self._partial, "xb")
        except OSError as err:  # a missing or read-only folder: named by `path`, not the temporary
            raise naming(err, self.path, self._partial)  # noqa: B904 (its cause set)
        try:
            if self._target.exists():  # its permissions stay, as when it was overwritten in place
                shutil.copymode(self._target, self._partial)
        except OSError:
            self.discard()
            raise

    def _write(self, data) -> None:
        try:
            self._file.write(data)
        except OSError as err:  # a full disk's error named no file
            raise naming(err, self.path, self._partial)  # noqa: B904 (its cause set)

    def write_bits(self, bits: np.ndarray) -> None:
        """Append bits [n, H, W], bool or 0/1 integers (other values refused: 256 wrapped to 0)."""
        bits = np.asarray(bits)
        _check_bits(bits)
        self._write(_C.spike_pack(bits, self._layout).data)

    def write_packed(self, packed: np.ndarray) -> None:
        """Append packed readouts uint8 [n, H, ceil(W/8)] in the memory layout."""
        packed = np.asarray(packed)
        shape = (self._memory.height, (self._memory.width + 7) // 8)
        if packed.dtype != np.uint8 or packed.ndim != 3 or packed.shape[1:] != shape:
            raise ValueError(
                f"packed readouts expected uint8 [n, {shape[0]}, {shape[1]}], found "
                f"{packed.dtype} {list(packed.shape)}"
            )
        n = len(packed)
        self._write(_C.spike_repack(packed, self._memory, 0, n, self._layout).data)

    def close(self) -> None:
        """Finish: the readouts written replace `path` (a symlink's target)."""
        if self._file.closed:
            return
        try:
            self._file.close()  # flushes: a full disk fails here
            self._partial.replace(self._target)
        except OSError as err:
            raise naming(err, self.path, self._partial)  # noqa: B904 (its cause set)
        finally:
            self._partial.unlink(missing_ok=True)  # gone once it replaced the target

    def discard(self) -> None:
        """Stop without touching `path`: the readouts written so far are deleted."""
        if self._file.closed:
            return
        try:
            self._file.close()  # flushes again what a full disk refused: fails again
        except OSError:
            pass  # the error that led here is the one to report
        finally:
            self._partial.unlink(missing_ok=True)

    def __del__(self) -> None:
        """A writer dropped unclosed leaves no hidden file (one was left for good), with a
        ResourceWarning, as an unclosed file gives; `path` is untouched."""
        file = getattr(self, "_file", None)  # (None where __init__ failed before it)
        if file is not None and not file.closed:
            warnings.warn(
                f"DatWriter {self.path}: dropped without close(), its readouts discarded and "
                f"{self.path.name} untouched (write in a with block, or close it)",
                ResourceWarning,
                stacklevel=2,
            )
            self.discard()

    def __enter__(self) -> DatWriter:
        return self

    def __exit__(self, error_type, *exc) -> None:
        self.discard() if error_type else self.close()


def check_chunk(chunk) -> None:
    """ValueError unless `chunk` (readouts handled at a time) is a positive int."""
    if whole_numbers(chunk=chunk)[0] < 1:
        raise ValueError(f"chunk expected a positive int (readouts at a time), found {chunk!r}")


def save_dat(path: PathLike, bits: np.ndarray, flip: bool = True, chunk: int = 1024) -> Path:
    """Write bits [T, H, W] (bool or 0/1) as a .dat file, `chunk` readouts at a time."""
    check_chunk(chunk)
    bits = _readouts_of(bits)
    with DatWriter(path, bits.shape[1], bits.shape[2], flip) as writer:
        for t in range(0, len(bits), chunk):
            writer.write_bits(bits[t : t + chunk])
    return Path(path)
