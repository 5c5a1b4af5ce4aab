"""A rendered (or recorded) session as arrays: what every method of the evaluation is fed.

The evaluation renders each motion once and feeds the same measurements to every method, so a
:class:`Session` holds everything a method or a metric needs, and nothing else:

* ``t`` ``(T,)`` frame times in seconds, strictly increasing;
* ``raw`` ``(T, 12, 3)`` the extracted landmarks in the camera frame C (stage S2's output, NaN where
  missing) — the paper's "Raw" method;
* ``visibility`` ``(T, 12)`` and ``pixels`` ``(T, 12, 2)`` the detector's scores and pixel positions,
  which the occlusion filter needs;
* ``truth`` ``(T, 12, 3)`` the true joint centres in C (the paper's Vicon reference);
* ``intrinsics`` the camera's :class:`~akc_drake.core.camera.CameraIntrinsics`;
* ``motion`` a name ("I", "II", "tpose", a file stem, ...);
* ``cycle_starts`` ``(C,)`` the first frame of every motion cycle (``[0]`` when cycles do not apply);
* ``source_time_s`` ``(T,)`` the time stages S1 + S2 took for each frame (NaN when unknown).

Sessions are saved as ``.npz`` without pickle (:meth:`Session.save_npz` / :meth:`Session.load_npz`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.fileio import atomic_save_npz

#: Format version written into every ``.npz`` so a future change can be detected on load.
SESSION_FORMAT = 1

_ARRAY_FIELDS = ("t", "raw", "visibility", "pixels", "truth", "cycle_starts", "source_time_s")


def _as_float(a, name: str, shape: tuple) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"Session.{name} must have shape {shape}, got {arr.shape}")
    return arr


@dataclass
class Session:
    """One motion as arrays (see the module docstring for the fields and their shapes).

    Raises:
        ValueError: naming the field when a shape, the times or the cycle boundaries are inconsistent.
    """

    t: np.ndarray
    raw: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray
    truth: np.ndarray
    intrinsics: CameraIntrinsics = field(default_factory=CameraIntrinsics)
    motion: str = "session"
    cycle_starts: np.ndarray | None = None
    source_time_s: np.ndarray | None = None

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        if t.ndim != 1 or t.size == 0:
            raise ValueError(f"Session.t must be a non-empty 1-D array of times, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ValueError("Session.t must be finite")
        if t.size > 1 and not np.all(np.diff(t) > 0):
            k = int(np.argmin(np.diff(t) > 0))
            raise ValueError(
                f"Session.t must be strictly increasing; t[{k}] = {t[k]:g}, t[{k + 1}] = {t[k + 1]:g}"
            )
        T = t.size
        self.t = t
        self.raw = _as_float(self.raw, "raw", (T, NUM_LANDMARKS, 3))
        self.visibility = _as_float(self.visibility, "visibility", (T, NUM_LANDMARKS))
        self.pixels = _as_float(self.pixels, "pixels", (T, NUM_LANDMARKS, 2))
        self.truth = _as_float(self.truth, "truth", (T, NUM_LANDMARKS, 3))
        if not isinstance(self.intrinsics, CameraIntrinsics):
            raise ValueError(
                f"Session.intrinsics must be a CameraIntrinsics, got {type(self.intrinsics).__name__}"
            )
        self.motion = str(self.motion)
        if self.cycle_starts is None:
            self.cycle_starts = np.zeros(1, dtype=np.int64)
        cs = np.asarray(self.cycle_starts)
        if cs.ndim != 1 or cs.size == 0 or not np.issubdtype(cs.dtype, np.number):
            raise ValueError(
                f"Session.cycle_starts must be a non-empty 1-D array of frame indices, got {cs!r}"
            )
        if not np.all(cs == np.round(cs)):
            raise ValueError(f"Session.cycle_starts must hold integer frame indices, got {cs!r}")
        cs = cs.astype(np.int64)
        if cs[0] != 0 or np.any(np.diff(cs) <= 0) or cs[-1] >= T:
            raise ValueError(
                "Session.cycle_starts must start at 0, increase strictly and stay below "
                f"{T} frames, got {cs.tolist()}"
            )
        self.cycle_starts = cs
        if self.source_time_s is None:
            self.source_time_s = np.full(T, np.nan)
        self.source_time_s = _as_float(self.source_time_s, "source_time_s", (T,))

    # ------------------------------------------------------------------ properties
    @property
    def num_frames(self) -> int:
        return int(self.t.size)

    @property
    def num_cycles(self) -> int:
        return int(self.cycle_starts.size)

    @property
    def dt(self) -> float:
        """The nominal frame period (median time step; ``1 / rate_hz`` for a single frame)."""
        if self.t.size < 2:
            return 1.0 / self.intrinsics.rate_hz
        return float(np.median(np.diff(self.t)))

    def cycle_index(self) -> np.ndarray:
        """``(T,)`` the cycle each frame belongs to (0-based)."""
        idx = np.zeros(self.num_frames, dtype=np.int64)
        for k, start in enumerate(self.cycle_starts[1:], start=1):
            idx[start:] = k
        return idx

    def cycle_slices(self) -> list[slice]:
        """One slice of frames per cycle, in order."""
        ends = list(self.cycle_starts[1:]) + [self.num_frames]
        return [slice(int(a), int(b)) for a, b in zip(self.cycle_starts, ends, strict=True)]

    def evaluation_mask(self, exclude_first_cycle: bool = True) -> np.ndarray:
        """``(T,)`` bool: the frames metrics are computed on.

        As in the paper, the first cycle is left out (it is the one the AKC weights were chosen on)
        when there is more than one cycle; a single-cycle session (or a motion file) is used whole.
        """
        mask = np.ones(self.num_frames, dtype=bool)
        if exclude_first_cycle and self.num_cycles > 1:
            mask[: self.cycle_starts[1]] = False
        return mask

    def evaluation_cycles(self, exclude_first_cycle: bool = True) -> list[slice]:
        """The cycles metrics are averaged over (all but the first when there are several)."""
        slices = self.cycle_slices()
        return slices[1:] if exclude_first_cycle and len(slices) > 1 else slices

    def subset(self, frames: slice) -> Session:
        """The frames ``frames`` (a slice with step 1) as a new session; cycles inside it are kept."""
        start, stop, step = frames.indices(self.num_frames)
        if step != 1 or stop <= start:
            raise ValueError(f"Session.subset needs a non-empty slice with step 1, got {frames}")
        cs = self.cycle_starts[(self.cycle_starts >= start) & (self.cycle_starts < stop)] - start
        if cs.size == 0 or cs[0] != 0:
            cs = np.concatenate([[0], cs])
        return Session(
            t=self.t[start:stop],
            raw=self.raw[start:stop],
            visibility=self.visibility[start:stop],
            pixels=self.pixels[start:stop],
            truth=self.truth[start:stop],
            intrinsics=self.intrinsics,
            motion=self.motion,
            cycle_starts=cs,
            source_time_s=self.source_time_s[start:stop],
        )

    # ------------------------------------------------------------------ files
    def save_npz(self, path) -> Path:
        """Write the session to ``path`` (``.npz``, no pickle), atomically (temp file + rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {name: getattr(self, name) for name in _ARRAY_FIELDS}
        arrays["names"] = np.array(LANDMARKS, dtype="<U32")
        arrays["motion"] = np.array(self.motion, dtype=f"<U{max(len(self.motion), 1)}")
        meta = json.dumps({"format": SESSION_FORMAT, "intrinsics": self.intrinsics.as_dict()})
        arrays["meta"] = np.array(meta, dtype=f"<U{len(meta)}")
        return atomic_save_npz(path, **arrays)

    @classmethod
    def load_npz(cls, path) -> Session:
        """Read a session written by :meth:`save_npz`.

        Raises:
            UserError: naming the file and the missing or bad field.
        """
        path = Path(path)
        if not path.is_file():
            raise UserError(f"{path}: no such session file")
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError) as e:
            raise UserError(f"{path}: not a session .npz file ({e})") from None
        missing = [k for k in (*_ARRAY_FIELDS, "names", "motion", "meta") if k not in data]
        if missing:
            raise UserError(f"{path}: missing field(s) {', '.join(missing)}")
        try:
            meta = json.loads(str(data["meta"]))
        except json.JSONDecodeError as e:
            raise UserError(f"{path}: field meta is not valid JSON ({e})") from None
        if meta.get("format") != SESSION_FORMAT:
            raise UserError(f"{path}: field meta.format is {meta.get('format')!r}, expected {SESSION_FORMAT}")
        names = tuple(str(n) for n in data["names"])
        if names != LANDMARKS:
            raise UserError(f"{path}: field names {names} does not match the landmark order {LANDMARKS}")
        try:
            intr = CameraIntrinsics.from_dict(meta.get("intrinsics"), where=f"{path}: meta.intrinsics")
            return cls(
                t=data["t"],
                raw=data["raw"],
                visibility=data["visibility"],
                pixels=data["pixels"],
                truth=data["truth"],
                intrinsics=intr,
                motion=str(data["motion"]),
                cycle_starts=data["cycle_starts"],
                source_time_s=data["source_time_s"],
            )
        except ValueError as e:
            raise UserError(f"{path}: {e}") from None


def cycle_starts_for(t: np.ndarray, cycle_s: float | None) -> np.ndarray:
    """First frame of every ``cycle_s``-long cycle of the frame times ``t`` (``[0]`` when None).

    A frame belongs to cycle ``floor((t - t[0]) / cycle_s)``, with a small tolerance so that
    frames sampled exactly on a boundary start the new cycle despite rounding; a last cycle shorter
    than half a period is merged into the one before.
    """
    t = np.asarray(t, dtype=float)
    if cycle_s is None:
        return np.zeros(1, dtype=np.int64)
    if not (math.isfinite(cycle_s) and cycle_s > 0):
        raise ValueError(f"cycle_s must be a positive number of seconds, got {cycle_s!r}")
    k = np.floor((t - t[0]) / cycle_s + 1e-6).astype(np.int64)
    starts = np.flatnonzero(np.diff(k, prepend=-1) > 0)
    # A trailing fragment shorter than half a cycle (e.g. the single frame sampled at the end time of
    # the last cycle) belongs to the cycle before it.
    if starts.size > 1 and t[-1] - t[starts[-1]] < 0.5 * cycle_s - 1e-9:
        starts = starts[:-1]
    return starts.astype(np.int64)


def cycle_starts_from_times(t: np.ndarray, start_times) -> np.ndarray:
    """Frame indices of cycles starting at ``start_times`` (seconds, on the same clock as ``t``).

    Each start maps to the first frame at or after it (within 1 µs); starts after the last frame are
    dropped, and a last cycle shorter than half the median cycle is merged into the one before.
    """
    t = np.asarray(t, dtype=float)
    st = np.asarray(start_times, dtype=float).reshape(-1)
    idx = np.searchsorted(t, st - 1e-6, side="left")
    idx = np.unique(np.concatenate([[0], idx[idx < t.size]])).astype(np.int64)
    if idx.size > 2:
        lengths = np.diff(np.concatenate([idx, [t.size]]))
        if lengths[-1] < 0.5 * np.median(lengths[:-1]):
            idx = idx[:-1]
    return idx


def _field(obj, *names):
    for name in names:
        if isinstance(obj, dict) and name in obj:
            return obj[name]
        if hasattr(obj, name):
            return getattr(obj, name)
    return None


def session_from_render(
    rendered,
    *,
    intrinsics: CameraIntrinsics | None = None,
    motion: str | None = None,
    cycle_s: float | None = None,
    source_time_s=None,
    use_render_cycles: bool = True,
) -> Session:
    """Adapt the renderer's output (``render_session(...)``) to an evaluation :class:`Session`.

    Args:
        rendered: an object (or mapping) with ``t``, ``landmarks_C`` (or ``raw``), ``visibility``,
            ``pixels`` and ``truth`` (or ``landmarks_true_C``); optional ``intrinsics``, ``motion``
            (or ``name``), ``source_time_s`` (or ``frame_time_s``).
        intrinsics: the camera's intrinsics when ``rendered`` does not carry them.
        motion: the session's name (default: the renderer's, else "session").
        cycle_s: the motion's cycle period in seconds, used when ``rendered`` carries no cycle start
            times; None (and no start times) when cycles do not apply.
        source_time_s: ``(T,)`` per-frame time of stages S1 + S2 when ``rendered`` does not carry it.
        use_render_cycles: use the renderer's ``cycle_starts`` (start times, seconds) when present.

    Returns:
        The session, with cycle boundaries from the renderer's cycle start times, else from ``cycle_s``.
    """
    t = _field(rendered, "t", "times")
    raw = _field(rendered, "landmarks_C", "raw")
    truth = _field(rendered, "truth", "landmarks_true_C")
    vis = _field(rendered, "visibility")
    pix = _field(rendered, "pixels")
    for name, value in (
        ("t", t),
        ("landmarks_C", raw),
        ("truth", truth),
        ("visibility", vis),
        ("pixels", pix),
    ):
        if value is None:
            raise ValueError(f"renderer output has no field {name!r}")
    intr = intrinsics if intrinsics is not None else _field(rendered, "intrinsics")
    if intr is None:
        intr = CameraIntrinsics()
    name = motion if motion is not None else _field(rendered, "motion", "motion_name", "name")
    if name is not None and not isinstance(name, str):
        name = getattr(name, "name", None) or str(name)
    st = source_time_s if source_time_s is not None else _field(rendered, "source_time_s", "frame_time_s")
    t = np.asarray(t, dtype=float)
    render_cycles = _field(rendered, "cycle_starts") if use_render_cycles else None
    if render_cycles is not None and np.asarray(render_cycles).size:
        starts = cycle_starts_from_times(t, render_cycles)
    else:
        starts = cycle_starts_for(t, cycle_s)
    return Session(
        t=t,
        raw=raw,
        visibility=vis,
        pixels=pix,
        truth=truth,
        intrinsics=intr,
        motion=name or "session",
        cycle_starts=starts,
        source_time_s=st,
    )
