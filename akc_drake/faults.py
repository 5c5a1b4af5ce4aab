"""Fault injection: tracking loss, detector garbage and camera failures, for tests, the demo and ``soak``.

Everything here works on the stage-S2 output that :class:`~akc_drake.diagrams.Measurements` carries
(``landmarks_C (T, 12, 3)``, ``visibility (T, 12)``, ``pixels (T, 12, 2)``), or wraps a frame source. Inputs
are never modified; every function returns new arrays and a record of what it did, so a test can check the
pipeline's behaviour frame by frame. All randomness comes from ``numpy.random.default_rng(seed)``.

* :func:`inject_dropouts` -- tracking loss in bursts: the person leaves the view or the detector finds nobody
  (``person``), one arm leaves the frame (``left_arm`` / ``right_arm``), or a random subset of landmarks is
  lost (``subset``). A dropped landmark reads as the extractor reports a missing one: NaN position and pixel,
  visibility 0.
* :func:`inject_garbage` -- what a confused detector or a bad depth pixel produces, one frame at a time:
  landmarks jumping across the image, depth 0 or 65.535 m (the largest 16-bit depth in millimetres),
  visibility NaN, non-finite coordinates, left and right swapped.
* :class:`FaultyFrameSource` -- a frame source that raises (``mode="raise"``) or stops delivering
  (``mode="stop"``) after a given number of frames: a camera unplugged mid-run.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import INDEX, LANDMARKS, NUM_LANDMARKS

#: Kinds of tracking loss :func:`inject_dropouts` draws from.
DROPOUT_KINDS: tuple[str, ...] = ("person", "left_arm", "right_arm", "subset")
#: Kinds of detector garbage :func:`inject_garbage` draws from.
GARBAGE_KINDS: tuple[str, ...] = ("jump", "depth_zero", "depth_far", "visibility_nan", "nonfinite", "swap")
#: The largest depth a 16-bit depth image in millimetres can hold, metres.
FAR_DEPTH_M = 65.535

#: Landmarks an arm leaving the frame takes with it (elbow, wrist and hand).
_ARM_LANDMARKS = {
    side: np.array([INDEX[f"{side}_{j}"] for j in ("elbow", "wrist", "pinky", "index")], dtype=np.intp)
    for side in ("left", "right")
}
#: Row permutation that swaps every left landmark with its right counterpart.
SWAP_LEFT_RIGHT: np.ndarray = np.array(
    [
        INDEX[n.replace("left_", "right_")] if n.startswith("left_") else INDEX[n.replace("right_", "left_")]
        for n in LANDMARKS
    ],
    dtype=np.intp,
)


def _arrays(measurements) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Checked copies of ``(landmarks_C, visibility, pixels)`` of a Measurements (or Session)."""
    L = getattr(measurements, "landmarks_C", None)
    if L is None:
        L = getattr(measurements, "raw", None)
    if L is None:
        raise ValueError("measurements must have landmarks_C (or raw), visibility and pixels arrays")
    L = np.array(L, dtype=np.float64)
    if L.ndim != 3 or L.shape[1:] != (NUM_LANDMARKS, 3):
        raise ValueError(f"measurements.landmarks_C must have shape (T, {NUM_LANDMARKS}, 3), got {L.shape}")
    T = L.shape[0]
    V = np.array(measurements.visibility, dtype=np.float64)
    if V.shape != (T, NUM_LANDMARKS):
        raise ValueError(f"measurements.visibility must have shape ({T}, {NUM_LANDMARKS}), got {V.shape}")
    P = np.array(measurements.pixels, dtype=np.float64)
    if P.shape != (T, NUM_LANDMARKS, 2):
        raise ValueError(f"measurements.pixels must have shape ({T}, {NUM_LANDMARKS}, 2), got {P.shape}")
    return L, V, P


def _with_arrays(measurements, L: np.ndarray, V: np.ndarray, P: np.ndarray):
    """``measurements`` with new arrays (same type when it is a dataclass, else a diagrams.Measurements)."""
    if dataclasses.is_dataclass(measurements) and not isinstance(measurements, type):
        names = {f.name for f in dataclasses.fields(measurements)}
        key = "landmarks_C" if "landmarks_C" in names else "raw"
        return dataclasses.replace(measurements, **{key: L, "visibility": V, "pixels": P})
    from akc_drake.diagrams import Measurements

    return Measurements(L, V, P, getattr(measurements, "truth_C", None))


def _check_fraction(fraction, name: str = "fraction") -> float:
    try:
        f = float(fraction)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [0, 1], got {fraction!r}") from None
    if not (0.0 <= f <= 1.0):
        raise ValueError(f"{name} must be in [0, 1], got {fraction!r}")
    return f


def _check_kinds(kinds, known: tuple[str, ...], name: str) -> tuple[str, ...]:
    ks = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    bad = [k for k in ks if k not in known]
    if not ks or bad:
        raise ValueError(f"{name} must be names from {', '.join(known)}, got {kinds!r}")
    return ks


@dataclass(frozen=True)
class Burst:
    """One tracking-loss burst: frames ``start`` to ``stop - 1`` lose ``landmarks``.

    Attributes:
        start, stop: the burst's frames, ``[start, stop)``.
        kind: one of :data:`DROPOUT_KINDS`.
        landmarks: ``(12,)`` bool, the landmarks lost during the burst.
    """

    start: int
    stop: int
    kind: str
    landmarks: np.ndarray

    @property
    def num_frames(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class DropoutPlan:
    """Where :func:`inject_dropouts` removed landmarks.

    Attributes:
        mask: ``(T, 12)`` bool, the landmark is lost in that frame.
        bursts: the bursts in time order (disjoint, separated by at least ``min_gap`` clean frames).
    """

    mask: np.ndarray
    bursts: tuple[Burst, ...]

    @property
    def frames(self) -> np.ndarray:
        """``(T,)`` bool: some landmark is lost in that frame."""
        return self.mask.any(axis=1)

    @property
    def fraction(self) -> float:
        """The share of frames with a loss."""
        return float(self.frames.mean()) if self.mask.size else 0.0


def plan_dropouts(
    num_frames: int,
    fraction: float,
    seed: int = 0,
    *,
    burst_s: tuple[float, float] = (0.5, 3.0),
    rate_hz: float = 10.0,
    kinds: Sequence[str] = DROPOUT_KINDS,
    start_frame: int = 0,
    min_gap: int = 1,
) -> DropoutPlan:
    """Draw tracking-loss bursts covering ``fraction`` of the frames from ``start_frame`` on.

    Burst lengths are uniform in ``burst_s`` seconds (at least one frame); each burst's kind is drawn
    uniformly from ``kinds`` (for ``subset``, each landmark is lost with probability 1/2, at least one).
    The bursts are laid out with random clean gaps of at least ``min_gap`` frames between them; the number
    of lost frames is ``round(fraction * (num_frames - start_frame))`` exactly (when the gaps do not fit,
    the last bursts are merged).

    Args:
        num_frames: ``T``.
        fraction: share of frames with a loss, in [0, 1].
        seed: the random seed.
        burst_s: ``(shortest, longest)`` burst duration in seconds.
        rate_hz: the camera rate (frames per second).
        kinds: the kinds of loss to draw from (:data:`DROPOUT_KINDS`).
        start_frame: frames before this one are left clean (e.g. to let the filter start).
        min_gap: clean frames between two bursts (>= 1, so that bursts stay distinct).

    Returns:
        The :class:`DropoutPlan`.

    Raises:
        ValueError: naming the argument and value.
    """
    T = int(num_frames)
    if T < 0:
        raise ValueError(f"num_frames must be >= 0, got {num_frames!r}")
    f = _check_fraction(fraction)
    ks = _check_kinds(kinds, DROPOUT_KINDS, "kinds")
    lo, hi = (float(b) for b in burst_s)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
        raise ValueError(
            f"burst_s must be (shortest, longest) seconds with 0 < shortest <= longest, got {burst_s!r}"
        )
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
    if not (0 <= int(start_frame) <= T):
        raise ValueError(f"start_frame must be in [0, {T}], got {start_frame!r}")
    if int(min_gap) < 1:
        raise ValueError(f"min_gap must be >= 1 frame, got {min_gap!r}")
    start_frame, min_gap = int(start_frame), int(min_gap)
    rng = np.random.default_rng(seed)
    span = T - start_frame
    target = int(round(f * span))
    lengths: list[int] = []
    while sum(lengths) < target:
        lengths.append(max(1, int(round(rng.uniform(lo, hi) * rate_hz))))
    if lengths:
        lengths[-1] -= sum(lengths) - target
        if lengths[-1] <= 0:
            lengths.pop()
    # Gaps: one before each burst (the first may be 0) and one after the last; inner gaps >= min_gap.
    while lengths and span - sum(lengths) < min_gap * (len(lengths) - 1):
        # Not enough clean frames to separate them: merge the two last bursts.
        last = lengths.pop()
        lengths[-1] += last
    clean = span - sum(lengths)
    n = len(lengths)
    mask = np.zeros((T, NUM_LANDMARKS), dtype=bool)
    bursts: list[Burst] = []
    if n:
        free = clean - min_gap * (n - 1)
        cuts = np.sort(rng.integers(0, free + 1, size=n))
        extra = np.diff(np.concatenate(([0], cuts)))  # extra clean frames before each burst
        k = start_frame
        for i, length in enumerate(lengths):
            k += int(extra[i]) + (min_gap if i else 0)
            kind = ks[int(rng.integers(len(ks)))]
            lost = np.zeros(NUM_LANDMARKS, dtype=bool)
            if kind == "person":
                lost[:] = True
            elif kind in ("left_arm", "right_arm"):
                lost[_ARM_LANDMARKS[kind.split("_")[0]]] = True
            else:
                lost = rng.random(NUM_LANDMARKS) < 0.5
                if not lost.any():
                    lost[int(rng.integers(NUM_LANDMARKS))] = True
            mask[k : k + length] = lost
            bursts.append(Burst(k, k + length, kind, lost))
            k += length
    return DropoutPlan(mask, tuple(bursts))


def dropout_plan(num_frames: int, bursts: Sequence[tuple]) -> DropoutPlan:
    """A :class:`DropoutPlan` from explicit bursts, for scripted scenarios.

    Args:
        num_frames: ``T``.
        bursts: ``(start, stop, what)`` per burst, frames ``[start, stop)``; ``what`` is a kind of
            :data:`DROPOUT_KINDS` other than ``subset`` or an iterable of landmark names.

    Raises:
        ValueError: a burst outside ``[0, T)``, empty, overlapping another, or an unknown kind/landmark.
    """
    T = int(num_frames)
    mask = np.zeros((T, NUM_LANDMARKS), dtype=bool)
    out: list[Burst] = []
    for i, (start, stop, what) in enumerate(sorted(bursts, key=lambda b: b[0])):
        start, stop = int(start), int(stop)
        if not (0 <= start < stop <= T):
            raise ValueError(f"bursts[{i}]: frames [{start}, {stop}) must be a non-empty range in [0, {T})")
        if mask[start:stop].any():
            raise ValueError(f"bursts[{i}]: frames [{start}, {stop}) overlap an earlier burst")
        lost = np.zeros(NUM_LANDMARKS, dtype=bool)
        if isinstance(what, str):
            if what == "person":
                lost[:] = True
            elif what in ("left_arm", "right_arm"):
                lost[_ARM_LANDMARKS[what.split("_")[0]]] = True
            else:
                raise ValueError(f"bursts[{i}]: kind must be person, left_arm or right_arm, got {what!r}")
            kind = what
        else:
            names = list(what)
            unknown = [n for n in names if n not in INDEX]
            if unknown or not names:
                raise ValueError(f"bursts[{i}]: unknown landmark name(s) {unknown or names!r}")
            lost[[INDEX[n] for n in names]] = True
            kind = "subset"
        mask[start:stop] = lost
        out.append(Burst(start, stop, kind, lost))
    return DropoutPlan(mask, tuple(out))


def apply_dropouts(measurements, plan: DropoutPlan):
    """``measurements`` with the landmarks of ``plan.mask`` lost (NaN position and pixel, visibility 0)."""
    L, V, P = _arrays(measurements)
    if plan.mask.shape != V.shape:
        raise ValueError(f"plan.mask has shape {plan.mask.shape}, the measurements {V.shape}")
    L[plan.mask] = np.nan
    P[plan.mask] = np.nan
    V[plan.mask] = 0.0
    return _with_arrays(measurements, L, V, P)


def inject_dropouts(
    measurements,
    fraction: float,
    seed: int = 0,
    *,
    burst_s: tuple[float, float] = (0.5, 3.0),
    rate_hz: float = 10.0,
    kinds: Sequence[str] = DROPOUT_KINDS,
    start_frame: int = 0,
):
    """Random tracking loss in bursts: :func:`plan_dropouts` then :func:`apply_dropouts`.

    Args:
        measurements: a :class:`~akc_drake.diagrams.Measurements` (or an evaluation ``Session``).
        fraction, seed, burst_s, rate_hz, kinds, start_frame: see :func:`plan_dropouts`.

    Returns:
        ``(new_measurements, plan)``.
    """
    T = _arrays(measurements)[0].shape[0]
    plan = plan_dropouts(T, fraction, seed, burst_s=burst_s, rate_hz=rate_hz, kinds=kinds,
                         start_frame=start_frame)
    return apply_dropouts(measurements, plan), plan


@dataclass(frozen=True)
class GarbageLog:
    """Where :func:`inject_garbage` corrupted the measurements.

    Attributes:
        kind: ``(T,)`` str, the kind of garbage in each frame ("" for a clean frame).
        mask: ``(T, 12)`` bool, the landmarks corrupted in each frame (all of them for ``swap``).
    """

    kind: np.ndarray
    mask: np.ndarray

    @property
    def frames(self) -> np.ndarray:
        """``(T,)`` bool: the frame carries garbage."""
        return self.kind != ""


def corrupt_frame(
    landmarks_C: np.ndarray,
    visibility: np.ndarray,
    pixels: np.ndarray,
    kind: str,
    which: np.ndarray,
    rng: np.random.Generator,
    intrinsics: CameraIntrinsics,
) -> None:
    """Corrupt one frame in place with garbage of ``kind`` on the landmarks ``which`` ((12,) bool).

    ``jump``: new random pixels anywhere in the image, deprojected at a depth in [0.5, 4] m, visibility 0.9 (a
    confident wrong detection); ``depth_zero``: the point at depth 0 (the camera centre); ``depth_far``: the
    point at :data:`FAR_DEPTH_M` along its pixel's ray; ``visibility_nan``: visibility NaN; ``nonfinite``: one
    coordinate +-inf or NaN with visibility 1; ``swap``: every left landmark exchanged with its right one.
    """
    K = intrinsics
    if kind == "swap":
        landmarks_C[:] = landmarks_C[SWAP_LEFT_RIGHT]
        visibility[:] = visibility[SWAP_LEFT_RIGHT]
        pixels[:] = pixels[SWAP_LEFT_RIGHT]
        return
    idx = np.flatnonzero(which)
    if kind == "jump":
        u = rng.uniform(0.0, K.width - 1.0, idx.size)
        v = rng.uniform(0.0, K.height - 1.0, idx.size)
        z = rng.uniform(0.5, 4.0, idx.size)
        landmarks_C[idx] = np.column_stack(((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z))
        pixels[idx] = np.column_stack((u, v))
        visibility[idx] = 0.9
    elif kind in ("depth_zero", "depth_far"):
        uv = pixels[idx]
        ok = np.isfinite(uv).all(axis=1)
        uv = np.where(ok[:, None], uv, [K.cx, K.cy])
        pixels[idx] = uv
        ray = np.column_stack(((uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy, np.ones(idx.size)))
        landmarks_C[idx] = ray * (0.0 if kind == "depth_zero" else FAR_DEPTH_M)
        visibility[idx] = np.where(np.isfinite(visibility[idx]), np.maximum(visibility[idx], 0.8), 0.8)
    elif kind == "visibility_nan":
        visibility[idx] = np.nan
    elif kind == "nonfinite":
        axis = rng.integers(0, 3, idx.size)
        values = rng.choice(np.array([np.inf, -np.inf, np.nan]), idx.size)
        landmarks_C[idx, axis] = values
        visibility[idx] = 1.0
    else:
        raise ValueError(f"unknown garbage kind {kind!r}; expected one of {', '.join(GARBAGE_KINDS)}")


def inject_garbage(
    measurements,
    fraction: float,
    seed: int = 0,
    *,
    kinds: Sequence[str] = GARBAGE_KINDS,
    intrinsics: CameraIntrinsics | None = None,
    start_frame: int = 0,
):
    """Corrupt a random ``fraction`` of the frames (single frames) with detector garbage.

    Each corrupted frame gets one kind drawn uniformly from ``kinds`` on a random non-empty subset of the
    landmarks (all of them for ``swap``); see :func:`corrupt_frame` for what each kind does.

    Args:
        measurements: a :class:`~akc_drake.diagrams.Measurements` (or an evaluation ``Session``).
        fraction: share of frames to corrupt, in [0, 1].
        seed: the random seed.
        kinds: names from :data:`GARBAGE_KINDS`.
        intrinsics: the camera, for pixel <-> ray conversions (default: 640x480 D435).
        start_frame: frames before this one are left clean.

    Returns:
        ``(new_measurements, GarbageLog)``.
    """
    f = _check_fraction(fraction)
    ks = _check_kinds(kinds, GARBAGE_KINDS, "kinds")
    K = intrinsics if intrinsics is not None else CameraIntrinsics()
    L, V, P = _arrays(measurements)
    T = L.shape[0]
    if not (0 <= int(start_frame) <= T):
        raise ValueError(f"start_frame must be in [0, {T}], got {start_frame!r}")
    rng = np.random.default_rng(seed)
    candidates = np.arange(int(start_frame), T)
    n = int(round(f * candidates.size))
    frames = np.sort(rng.choice(candidates, size=n, replace=False)) if n else np.zeros(0, dtype=int)
    kind = np.full(T, "", dtype=object)
    mask = np.zeros((T, NUM_LANDMARKS), dtype=bool)
    for k in frames:
        kd = ks[int(rng.integers(len(ks)))]
        which = rng.random(NUM_LANDMARKS) < 0.5
        if not which.any():
            which[int(rng.integers(NUM_LANDMARKS))] = True
        if kd == "swap":
            which[:] = True
        corrupt_frame(L[k], V[k], P[k], kd, which, rng, K)
        kind[k] = kd
        mask[k] = which
    return _with_arrays(measurements, L, V, P), GarbageLog(kind.astype(str), mask)


class FaultyFrameSource:
    """A frame source that fails after ``fail_after`` frames: a camera unplugged or a stream that dries up.

    Wraps any frame source (see :mod:`akc_drake.io.sources`). Frames ``0 .. fail_after - 1`` are the inner
    source's; asking for frame ``fail_after`` raises ``RuntimeError`` (``mode="raise"``) or ends the
    iteration (``mode="stop"``). Random access (``len`` / ``[]``) is offered only when the inner source
    has it; with ``mode="raise"`` ``len`` is the inner length, so a reader that trusts it still meets the
    fault, with ``mode="stop"`` it is ``fail_after``.

    Args:
        source: the inner frame source (with ``intrinsics`` and ``rate_hz``).
        fail_after: number of good frames (>= 0).
        mode: ``"raise"`` or ``"stop"``.
    """

    def __new__(cls, source, *args, **kwargs):
        if cls is FaultyFrameSource and hasattr(source, "__len__") and hasattr(source, "__getitem__"):
            cls = _FaultyRandomAccessSource
        return super().__new__(cls)

    def __init__(self, source, fail_after: int, mode: str = "raise"):
        if mode not in ("raise", "stop"):
            raise ValueError(f"mode must be 'raise' or 'stop', got {mode!r}")
        if isinstance(fail_after, bool) or not isinstance(fail_after, (int, np.integer)) or fail_after < 0:
            raise ValueError(f"fail_after must be an integer >= 0, got {fail_after!r}")
        self._inner = source
        self.fail_after = int(fail_after)
        self.mode = mode
        self.intrinsics = source.intrinsics
        self.rate_hz = getattr(source, "rate_hz", source.intrinsics.rate_hz)

    def _fault(self, k: int):
        raise RuntimeError(f"simulated camera fault: the device stopped responding at frame {k}")

    def __iter__(self) -> Iterator:
        for k, frame in enumerate(self._inner):
            if k >= self.fail_after:
                if self.mode == "raise":
                    self._fault(k)
                return
            yield frame

    def close(self) -> None:
        close = getattr(self._inner, "close", None)
        if close is not None:
            close()

    def __getattr__(self, name):
        # Anything else (ground_truth, path, ...) is the inner source's.
        if name.startswith("__") or name == "_inner":
            raise AttributeError(name)
        return getattr(self._inner, name)


class _FaultyRandomAccessSource(FaultyFrameSource):
    """:class:`FaultyFrameSource` over a source with random access (``mode="stop"``: a shorter source)."""

    def __len__(self) -> int:
        n = len(self._inner)
        return n if self.mode == "raise" else min(n, self.fail_after)

    def __getitem__(self, k: int):
        if k >= self.fail_after:
            if self.mode == "raise":
                self._fault(k)
            raise IndexError(f"frame {k} out of range: the source stopped after {self.fail_after} frames")
        return self._inner[k]


@dataclass(frozen=True)
class ChainRun:
    """Per camera frame, what stages S3-S5 made of a measurement sequence (see :func:`run_target_chain`).

    Attributes:
        accepted: ``(T, 12, 3)`` the occlusion filter's output.
        status: ``(T, 12)`` the filter's tracking status codes (:mod:`akc_drake.core.kalman`).
        estimated: ``(T, 12, 3)`` the filter's output.
        corrected: ``(T, 12, 3)`` the corrector's output.
        X_TE: ``{"left": (T, 4, 4), "right": (T, 4, 4)}`` the robot targets.
        tracking_lost: ``(T, 2)`` FrameMapper's flags (left, right).
    """

    accepted: np.ndarray
    status: np.ndarray
    estimated: np.ndarray
    corrected: np.ndarray
    X_TE: dict
    tracking_lost: np.ndarray


def run_target_chain(measurements, config=None, *, teleop: bool = True, dims=None) -> ChainRun:
    """Run the occlusion filter, the filter, the corrector and FrameMapper of the teleop diagram (no robot).

    The same systems and settings as :func:`~akc_drake.diagrams.build_teleop_diagram` (``teleop=True``) or
    the mocap diagram (``teleop=False``) builds, stepped one camera frame at a time: a quick way to see what
    the robot would be told under faults.

    Args:
        measurements: a :class:`~akc_drake.diagrams.Measurements`.
        config: the :class:`~akc_drake.config.PipelineConfig` (default: its defaults).
        teleop: the teleop diagram's settings (gate, short prediction, swap fix, anatomical check).
        dims: body dimensions (default: ``config.dims``, else the simulated operator's).

    Returns:
        The :class:`ChainRun`.
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from akc_drake import diagrams
    from akc_drake.config import PipelineConfig
    from akc_drake.systems import timing
    from akc_drake.systems.frame_mapper import FrameMapper

    cfg = (config or PipelineConfig()).validate()
    period = diagrams.camera_period(cfg)
    dims = dims if dims is not None else diagrams.resolve_dims(cfg)
    builder = DiagramBuilder()
    src = diagrams.AddMeasurementSource(builder, cfg, replay=measurements)
    ports = diagrams.AddMocapPipeline(builder, cfg, dims, src, teleop=teleop)
    mapper = builder.AddSystem(FrameMapper(period_s=period, stage_offset_s=cfg.stage_offset_s))
    builder.Connect(ports.corrected, mapper.GetInputPort("landmarks_C"))
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.Initialize()
    root = sim.get_context()
    kf = ports.systems.get("filter")
    done = timing.stage_offset("mapper", cfg.stage_offset_s) + 0.5 * cfg.stage_offset_s
    T = int(measurements.num_frames)
    acc, status, est, corr, lost = [], [], [], [], []
    X = {"left": [], "right": []}
    mctx = mapper.GetMyContextFromRoot(root)

    def value(port):
        return np.array(port.Eval(port.get_system().GetMyContextFromRoot(root)), dtype=float)

    for k in range(T):
        sim.AdvanceTo(k * period + done)
        acc.append(value(ports.accepted))
        est.append(value(ports.estimated))
        corr.append(value(ports.corrected))
        if kf is not None:
            status.append(value(kf.GetOutputPort("tracking_status")))
        else:
            status.append(np.full(NUM_LANDMARKS, np.nan))
        for side in ("left", "right"):
            X[side].append(mapper.GetOutputPort(f"X_TE_desired_{side}").Eval(mctx).GetAsMatrix4())
        lost.append(value(mapper.GetOutputPort("tracking_lost")))
    shape = (T, NUM_LANDMARKS, 3)
    return ChainRun(
        accepted=np.array(acc).reshape(shape),
        status=np.array(status),
        estimated=np.array(est).reshape(shape),
        corrected=np.array(corr).reshape(shape),
        X_TE={s: np.array(v) for s, v in X.items()},
        tracking_lost=np.array(lost),
    )
