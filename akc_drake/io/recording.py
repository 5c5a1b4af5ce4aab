"""The recording folder: what ``akc-drake record`` writes and ``--source recording:DIR`` reads.

Layout (see DESIGN.md)::

    DIR/intrinsics.json      {"width", "height", "fx", "fy", "cx", "cy", "depth_scale", "rate_hz"}
    DIR/color/000000.png     RGB frames, stored by OpenCV as 8-bit BGR PNG
    DIR/depth/000000.png     uint16 depth, ``depth_scale`` metres per unit, 0 = no depth
    DIR/timestamps.csv       header ``index,t``; one row per frame, t in seconds, strictly increasing
    DIR/ground_truth.npz     simulated recordings only: ``t`` (T,), ``names`` (J,) fixed-width unicode,
                             ``landmarks`` (T, J, 3) in the camera frame C, metres

Crash safety: the frame PNGs, ``intrinsics.json`` and ``ground_truth.npz`` are written to a temporary
name and renamed into place, so such a file either holds its previous complete content or its new
complete content. ``timestamps.csv`` gets its header the same way, then one appended row per frame,
flushed at once (a killed process loses no listed frame) and synced to the disk every ``sync_every``
rows and on close (a power cut loses at most those rows; a torn last row is ignored by the reader).
The frame PNGs are written before the frame's row is appended, so every listed frame is complete.
``ground_truth.npz`` is rewritten every ``checkpoint_every`` frames and on :meth:`RecordingWriter.close`;
after a crash it may cover fewer frames than ``timestamps.csv``, and the reader then gives the later
frames no ground truth.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

import cv2
import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write, atomic_write_bytes

INTRINSICS_FILE = "intrinsics.json"
TIMESTAMPS_FILE = "timestamps.csv"
GROUND_TRUTH_FILE = "ground_truth.npz"
COLOR_DIR = "color"
DEPTH_DIR = "depth"
#: The keys ``intrinsics.json`` must have (all of CameraIntrinsics' fields).
INTRINSICS_KEYS: tuple[str, ...] = ("width", "height", "fx", "fy", "cx", "cy", "depth_scale", "rate_hz")
_MAX_DEPTH_UNITS = np.iinfo(np.uint16).max


def frame_name(index: int) -> str:
    """File name of frame ``index`` inside ``color/`` and ``depth/``."""
    return f"{index:06d}.png"


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    atomic_write_bytes(path, data)


def _atomic_write_with(path: Path, writer) -> None:
    """Call ``writer(file_object)`` on a temporary file in ``path``'s folder, then rename it to ``path``."""
    atomic_write(path, writer)


def depth_to_units(depth_m: np.ndarray, depth_scale: float) -> np.ndarray:
    """Quantise a depth image in metres to uint16 units of ``depth_scale`` metres.

    Non-finite, non-positive and out-of-range depths (above ``65535 * depth_scale``) become 0, the
    "no depth" value.

    Args:
        depth_m: ``(H, W)`` depth in metres.
        depth_scale: metres per unit.

    Returns:
        ``(H, W)`` uint16.
    """
    d = np.asarray(depth_m, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        units = np.rint(d / depth_scale)
    valid = np.isfinite(units) & (units > 0) & (units <= _MAX_DEPTH_UNITS)
    return np.where(valid, units, 0).astype(np.uint16)


def units_to_depth(units: np.ndarray, depth_scale: float) -> np.ndarray:
    """uint16 depth units to float64 metres (0 stays 0 = no depth)."""
    return np.asarray(units).astype(np.float64) * float(depth_scale)


class RecordingWriter:
    """Writes a recording folder frame by frame.

    Use as a context manager; :meth:`close` (also called on leaving the ``with`` block, even on an
    exception) writes the final ``timestamps.csv`` and ``ground_truth.npz``.

    Args:
        out_dir: the folder (created if absent; must not already hold a recording).
        intrinsics: the camera's intrinsics; every frame must be ``width`` x ``height``.
        names: landmark names of the ground truth rows (default: :data:`~akc_drake.core.skeleton.LANDMARKS`).
        checkpoint_every: rewrite ``ground_truth.npz`` every this many frames (and on close).
        sync_every: sync ``timestamps.csv`` to the disk every this many rows (and on close).
        overwrite: allow writing into a folder that already holds ``timestamps.csv``.

    Raises:
        UserError: the folder already holds a recording (and ``overwrite`` is False) or cannot be created.
    """

    def __init__(
        self,
        out_dir,
        intrinsics: CameraIntrinsics,
        *,
        names: Sequence[str] = LANDMARKS,
        checkpoint_every: int = 25,
        sync_every: int = 30,
        overwrite: bool = False,
    ):
        if not isinstance(intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}")
        self.out_dir = Path(out_dir)
        self.intrinsics = intrinsics
        self.names = tuple(str(n) for n in names)
        if not self.names:
            raise ValueError("names must not be empty")
        self.checkpoint_every = max(int(checkpoint_every), 1)
        self.sync_every = max(int(sync_every), 1)
        if self.out_dir.exists() and not self.out_dir.is_dir():
            raise UserError(f"{self.out_dir}: exists and is not a folder")
        if (self.out_dir / TIMESTAMPS_FILE).exists() and not overwrite:
            raise UserError(
                f"{self.out_dir}: already holds a recording ({TIMESTAMPS_FILE}); choose another --out"
            )
        try:
            (self.out_dir / COLOR_DIR).mkdir(parents=True, exist_ok=True)
            (self.out_dir / DEPTH_DIR).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UserError(f"{self.out_dir}: cannot create the recording folder ({e.strerror})") from None
        if overwrite:
            for stale in (TIMESTAMPS_FILE, GROUND_TRUTH_FILE):
                (self.out_dir / stale).unlink(missing_ok=True)
        _atomic_write_bytes(
            self.out_dir / INTRINSICS_FILE,
            (json.dumps(intrinsics.as_dict(), indent=2) + "\n").encode("utf-8"),
        )
        self._t: list[float] = []
        self._truth: list[np.ndarray] = []
        self._has_truth: bool | None = None
        self._closed = False
        self._truth_written = 0
        self._timestamps = None  # the open timestamps.csv, appended to (opened at the first frame)
        self._unsynced = 0

    def __len__(self) -> int:
        return len(self._t)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):
        # A writer dropped without close() (a crash being handled further up): release the file handle only;
        # every appended row is already flushed.
        f = getattr(self, "_timestamps", None)
        if f is not None and not f.closed:
            f.close()

    def write(
        self, t: float, color_rgb: np.ndarray, depth_m: np.ndarray, truth_C: np.ndarray | None = None
    ) -> int:
        """Append one frame.

        Args:
            t: timestamp in seconds, finite and greater than the previous frame's.
            color_rgb: ``(H, W, 3)`` uint8 RGB.
            depth_m: ``(H, W)`` depth in metres (0 or NaN where invalid); quantised to ``depth_scale``.
            truth_C: ``(J, 3)`` true landmark positions in C (J = len(names)), or None. Either every
                frame has it or none does.

        Returns:
            The frame's index.

        Raises:
            ValueError: a wrong shape/dtype, a non-increasing t, or ground truth given for only some frames.
        """
        if self._closed:
            raise ValueError(f"{self.out_dir}: the recording is closed")
        K = self.intrinsics
        i = len(self._t)
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"frame {i}: t must be finite, got {t!r}")
        if self._t and not t > self._t[-1]:
            raise ValueError(
                f"frame {i}: t = {t!r} s is not after the previous frame's t = {self._t[-1]!r} s"
            )
        color = np.asarray(color_rgb)
        if color.dtype != np.uint8 or color.shape != (K.height, K.width, 3):
            raise ValueError(
                f"frame {i}: color must be uint8 ({K.height}, {K.width}, 3), got {color.dtype} {color.shape}"
            )
        depth = np.asarray(depth_m)
        if depth.shape != (K.height, K.width):
            raise ValueError(f"frame {i}: depth must have shape ({K.height}, {K.width}), got {depth.shape}")
        has = truth_C is not None
        if self._has_truth is not None and has != self._has_truth:
            raise ValueError(
                f"frame {i}: truth_C is {'given' if has else 'missing'} but it was "
                f"{'missing' if has else 'given'} for the earlier frames"
            )
        if has:
            truth = np.asarray(truth_C, dtype=np.float64)
            if truth.shape != (len(self.names), 3):
                raise ValueError(
                    f"frame {i}: truth_C must have shape ({len(self.names)}, 3), got {truth.shape}"
                )
        ok, color_png = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(color), cv2.COLOR_RGB2BGR))
        ok2, depth_png = cv2.imencode(".png", depth_to_units(depth, K.depth_scale))
        if not (ok and ok2):
            raise ValueError(f"frame {i}: PNG encoding failed")
        _atomic_write_bytes(self.out_dir / COLOR_DIR / frame_name(i), color_png.tobytes())
        _atomic_write_bytes(self.out_dir / DEPTH_DIR / frame_name(i), depth_png.tobytes())
        self._t.append(t)
        self._has_truth = has
        if has:
            self._truth.append(truth.copy())
        self._append_timestamp(i, t)
        if has and len(self._truth) - self._truth_written >= self.checkpoint_every:
            self._write_ground_truth()
        return i

    def _append_timestamp(self, i: int, t: float) -> None:
        """Append frame ``i``'s row to ``timestamps.csv`` (the header first, atomically), flushed at once."""
        if self._timestamps is None:
            path = self.out_dir / TIMESTAMPS_FILE
            _atomic_write_bytes(path, b"index,t\n")
            self._timestamps = open(path, "a", encoding="ascii", newline="")  # closed in close()
        self._timestamps.write(f"{i},{t!r}\n")
        self._timestamps.flush()  # one write(2): a killed process leaves the row whole or absent
        self._unsynced += 1
        if self._unsynced >= self.sync_every:
            self._sync_timestamps()

    def _sync_timestamps(self) -> None:
        if self._timestamps is not None and self._unsynced:
            os.fsync(self._timestamps.fileno())
            self._unsynced = 0

    def _write_ground_truth(self) -> None:
        t = np.asarray(self._t[: len(self._truth)], dtype=np.float64)
        names = np.array(self.names, dtype=f"<U{max(len(n) for n in self.names)}")
        landmarks = np.stack(self._truth).astype(np.float64)
        _atomic_write_with(
            self.out_dir / GROUND_TRUTH_FILE,
            lambda f: np.savez(f, t=t, names=names, landmarks=landmarks),
        )
        self._truth_written = len(self._truth)

    def close(self) -> None:
        """Write the final ``timestamps.csv`` and ``ground_truth.npz``; later calls do nothing."""
        if self._closed:
            return
        self._closed = True
        if self._timestamps is None:
            _atomic_write_bytes(self.out_dir / TIMESTAMPS_FILE, b"index,t\n")  # no frames: the header alone
        else:
            try:
                self._sync_timestamps()
            finally:
                self._timestamps.close()
        if self._has_truth:
            self._write_ground_truth()


class RecordingReader:
    """Reads a recording folder; indexing and iteration give :class:`~akc_drake.core.camera.CameraFrame`.

    ``frame.truth_C`` is the ground truth in :data:`~akc_drake.core.skeleton.LANDMARKS` order
    (``(12, 3)``, NaN for landmarks the recording does not have) when ``ground_truth.npz`` covers the
    frame, else None. ``frame.extras`` holds ``{"index": i, "source": "recording"}``.

    Args:
        path: the recording folder.

    Raises:
        UserError: no folder, a missing or invalid ``intrinsics.json`` (naming the field) or
            ``timestamps.csv`` (naming the line), timestamps not strictly increasing, a listed frame
            whose PNG is missing, or an invalid ``ground_truth.npz``. Frame images are checked (size,
            type) when they are read; the first frame's at once, so that a recording whose
            ``intrinsics.json`` does not match its images fails when it is opened.
    """

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.exists():
            raise UserError(f"{self.path}: recording folder not found")
        if not self.path.is_dir():
            raise UserError(f"{self.path}: not a folder (a recording is a folder with {INTRINSICS_FILE})")
        self.intrinsics = self._load_intrinsics()
        self._t = self._load_timestamps()
        for i in range(len(self._t)):
            for sub in (COLOR_DIR, DEPTH_DIR):
                p = self.path / sub / frame_name(i)
                if not p.is_file():
                    raise UserError(f"{p}: missing (frame {i} is listed in {self.path / TIMESTAMPS_FILE})")
        self._gt = self._load_ground_truth()
        if self._gt is not None:
            t_gt, names, lm = self._gt
            self._truth_ordered = np.full((len(t_gt), NUM_LANDMARKS, 3), np.nan)
            for j, n in enumerate(names):
                if n in LANDMARKS:
                    self._truth_ordered[:, LANDMARKS.index(n)] = lm[:, j]
        if len(self._t):
            self[0]  # images against intrinsics.json: a mismatch is reported now, not mid-run

    # -- loading -----------------------------------------------------------------------------------

    def _load_intrinsics(self) -> CameraIntrinsics:
        p = self.path / INTRINSICS_FILE
        if not p.is_file():
            raise UserError(f"{p}: missing (not a recording folder?)")
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise UserError(f"{p}: not valid JSON ({e})") from None
        if not isinstance(d, dict):
            raise UserError(f"{p}: expected a JSON object with keys {', '.join(INTRINSICS_KEYS)}")
        missing = [k for k in INTRINSICS_KEYS if k not in d]
        if missing:
            raise UserError(f"{p}: missing field(s) {', '.join(missing)}")
        unknown = [k for k in d if k not in INTRINSICS_KEYS]
        if unknown:
            raise UserError(f"{p}: unknown field(s) {', '.join(map(str, unknown))}")
        for k in INTRINSICS_KEYS:
            v = d[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise UserError(f"{p}: field {k} must be a number, got {v!r}")
        try:
            return CameraIntrinsics.from_dict(d, where=str(p))
        except ValueError as e:
            raise UserError(str(e)) from None

    def _load_timestamps(self) -> np.ndarray:
        p = self.path / TIMESTAMPS_FILE
        if not p.is_file():
            raise UserError(f"{p}: missing")
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError as e:
            raise UserError(f"{p}: not a text file ({e})") from None
        rows = list(csv.reader(text.splitlines()))
        # A last row without its newline was torn by a crash (the writer appends whole rows): ignore it
        # when it does not parse.
        torn_line = len(rows) if len(rows) > 1 and not text.endswith("\n") else None
        if not rows or [c.strip() for c in rows[0]] != ["index", "t"]:
            got = ",".join(rows[0]) if rows else "an empty file"
            raise UserError(f"{p}: line 1 must be the header 'index,t', got {got!r}")
        ts: list[float] = []
        for line_no, row in enumerate(rows[1:], start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if line_no == torn_line:
                try:
                    self._parse_row(p, line_no, row, ts)
                except UserError:
                    break
                continue
            self._parse_row(p, line_no, row, ts)
        return np.asarray(ts, dtype=np.float64)

    @staticmethod
    def _parse_row(p: Path, line_no: int, row: list[str], ts: list[float]) -> None:
        """Check one ``index,t`` row of ``p`` and append its t to ``ts``; UserError naming the line."""
        if len(row) != 2:
            raise UserError(f"{p}: line {line_no}: expected 'index,t', got {','.join(row)!r}")
        try:
            index = int(row[0])
        except ValueError:
            raise UserError(f"{p}: line {line_no}: index must be an integer, got {row[0]!r}") from None
        try:
            t = float(row[1])
        except ValueError:
            raise UserError(f"{p}: line {line_no}: t must be a number, got {row[1]!r}") from None
        if index != len(ts):
            raise UserError(
                f"{p}: line {line_no}: index must be {len(ts)} (frames count from 0), got {index}"
            )
        if not math.isfinite(t):
            raise UserError(f"{p}: line {line_no}: t must be finite, got {row[1]!r}")
        if ts and not t > ts[-1]:
            raise UserError(
                f"{p}: line {line_no}: timestamps not increasing (t = {t!r} after {ts[-1]!r})"
            )
        ts.append(t)

    def _load_ground_truth(self):
        p = self.path / GROUND_TRUTH_FILE
        if not p.exists():
            return None
        try:
            with np.load(p, allow_pickle=False) as z:
                missing = [k for k in ("t", "names", "landmarks") if k not in z.files]
                if missing:
                    raise UserError(f"{p}: missing array(s) {', '.join(missing)}")
                t = np.asarray(z["t"])
                names = z["names"]
                lm = np.asarray(z["landmarks"])
        except UserError:
            raise
        except ValueError as e:  # e.g. an object array that would need pickle
            raise UserError(f"{p}: cannot be read without pickle ({e})") from None
        except (OSError, EOFError) as e:
            raise UserError(f"{p}: not a valid .npz file ({e})") from None
        if names.ndim != 1 or names.dtype.kind != "U":
            raise UserError(f"{p}: names must be a 1-D unicode array, got {names.dtype} {names.shape}")
        if t.ndim != 1 or t.dtype.kind != "f":
            raise UserError(f"{p}: t must be a 1-D float array, got {t.dtype} {t.shape}")
        if lm.shape != (len(t), len(names), 3) or lm.dtype.kind != "f":
            raise UserError(
                f"{p}: landmarks must be float ({len(t)}, {len(names)}, 3) (t, names, xyz), "
                f"got {lm.dtype} {lm.shape}"
            )
        if len(t) > len(self._t):
            raise UserError(f"{p}: t has {len(t)} frames but {TIMESTAMPS_FILE} lists {len(self._t)}")
        bad = np.flatnonzero(~np.isclose(t, self._t[: len(t)], rtol=0.0, atol=1e-9))
        if bad.size:
            i = int(bad[0])
            raise UserError(
                f"{p}: t[{i}] = {float(t[i])!r} does not match {TIMESTAMPS_FILE} ({float(self._t[i])!r})"
            )
        return t.astype(np.float64), tuple(str(n) for n in names), lm.astype(np.float64)

    # -- access ------------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self._t)

    @property
    def timestamps(self) -> np.ndarray:
        """``(T,)`` frame times in seconds (a copy)."""
        return self._t.copy()

    @property
    def rate_hz(self) -> float:
        return self.intrinsics.rate_hz

    def ground_truth(self) -> tuple[np.ndarray, tuple[str, ...], np.ndarray] | None:
        """``(t (T,), names (J,), landmarks (T, J, 3))`` as stored, or None for a real recording."""
        if self._gt is None:
            return None
        t, names, lm = self._gt
        return t.copy(), names, lm.copy()

    def _read_png(self, sub: str, i: int, flags: int) -> np.ndarray:
        p = self.path / sub / frame_name(i)
        if not p.is_file():
            raise UserError(f"{p}: missing (frame {i})")
        img = cv2.imread(str(p), flags)
        if img is None:
            raise UserError(f"{p}: not a readable PNG image")
        return img

    def __getitem__(self, i: int) -> CameraFrame:
        n = len(self._t)
        if not isinstance(i, (int, np.integer)):
            raise TypeError(f"recording index must be an integer, got {type(i).__name__}")
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"frame {i} out of range: {self.path} has {n} frames")
        K = self.intrinsics
        bgr = self._read_png(COLOR_DIR, i, cv2.IMREAD_COLOR)
        if bgr.shape != (K.height, K.width, 3) or bgr.dtype != np.uint8:
            raise UserError(
                f"{self.path / COLOR_DIR / frame_name(i)}: size {bgr.shape[1]}x{bgr.shape[0]} does not match "
                f"{INTRINSICS_FILE} width x height = {K.width}x{K.height}"
            )
        units = self._read_png(DEPTH_DIR, i, cv2.IMREAD_UNCHANGED)
        pd = self.path / DEPTH_DIR / frame_name(i)
        if units.ndim != 2 or units.dtype != np.uint16:
            raise UserError(
                f"{pd}: depth must be a single-channel 16-bit PNG, got {units.dtype} {units.shape}"
            )
        if units.shape != (K.height, K.width):
            raise UserError(
                f"{pd}: size {units.shape[1]}x{units.shape[0]} does not match "
                f"{INTRINSICS_FILE} width x height = {K.width}x{K.height}"
            )
        truth = None
        if self._gt is not None and i < len(self._truth_ordered):
            truth = self._truth_ordered[i].copy()
        return CameraFrame(
            color=cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB),
            depth_m=units_to_depth(units, K.depth_scale),
            t=float(self._t[i]),
            intrinsics=K,
            truth_C=truth,
            extras={"index": int(i), "source": "recording"},
        )

    def __iter__(self) -> Iterator[CameraFrame]:
        for i in range(len(self)):
            yield self[i]


def write_recording(out_dir, frames, intrinsics: CameraIntrinsics | None = None, **writer_opts) -> Path:
    """Write an iterable of :class:`~akc_drake.core.camera.CameraFrame` as a recording folder.

    Args:
        out_dir: the folder.
        frames: frames (``truth_C``, when present, must be in LANDMARKS order).
        intrinsics: defaults to the first frame's.
        **writer_opts: passed to :class:`RecordingWriter`.

    Returns:
        ``out_dir`` as a Path.
    """
    writer = None
    try:
        for f in frames:
            if writer is None:
                writer = RecordingWriter(out_dir, intrinsics or f.intrinsics, **writer_opts)
            writer.write(f.t, f.color, f.depth_m, f.truth_C)
    finally:
        if writer is not None:
            writer.close()
    if writer is None:
        raise ValueError("write_recording: no frames to write")
    return Path(out_dir)
