"""The compared methods as compositions of the core stages, run over a whole :class:`Session`.

A method is ``[occlusion filter ->] filter [-> corrector]``:

=============  =================  ===========  ==========
method         occlusion filter   filter       corrector
=============  =================  ===========  ==========
``Raw``        no                 none         none
``KF``         yes                KF           none
``EKF``        yes                EKF          none
``AKC(KF)``    yes                KF           AKC
``AKC(EKF)``   yes                EKF          AKC
``AKC+(KF)``   yes                KF           AKC+
``AKC+(EKF)``  yes                EKF          AKC+
``COIK(KF)``   yes                KF           COIK
``COIK(EKF)``  yes                EKF          COIK
=============  =================  ===========  ==========

A corrector of your own runs beside them as ``NAME(KF)`` / ``NAME(EKF)``: ``MethodOptions.correctors`` maps
``NAME`` to the import path of a factory (``"package.module:attribute"``, :func:`load_corrector`). It is given
what AKC+ is given, and is compared with its filter as AKC+ is.

The stages are the core objects the Drake LeafSystems wrap, called directly frame by frame, so the
accuracy and the speed measured here are those of the code the diagram runs. Shared prefixes are
computed once (:class:`MethodRunner`): AKC(KF) and COIK(KF) see exactly the same KF output, which is
both fair and fast. Every stage is timed per frame with ``time.perf_counter``.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.landmark_tracking import taken_measurement
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.evaluation.session import Session

#: Every method, in the order the paper's tables list them.
METHODS: tuple[str, ...] = (
    "Raw", "KF", "EKF", "COIK(KF)", "AKC(KF)", "AKC(EKF)", "AKC+(KF)", "AKC+(EKF)", "COIK(EKF)"
)

#: Stage names used in the per-frame timings.
STAGES: tuple[str, ...] = ("source", "occlusion", "filter", "corrector")

_FILTERS = ("none", "KF", "EKF")
_CORRECTORS = ("none", "AKC", "AKC+", "COIK")
_PATTERN = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_+-]*)\s*\(\s*(KF|EKF)\s*\)\s*$")
_LABEL = re.compile(r"^[A-Za-z][A-Za-z0-9_+-]*$")


@dataclass(frozen=True)
class MethodSpec:
    """What a method is made of.

    Attributes:
        name: the canonical name (e.g. ``"AKC(KF)"``).
        occlusion: whether the occlusion filter runs first.
        filter: ``"none"``, ``"KF"`` or ``"EKF"``.
        corrector: ``"none"``, ``"AKC"`` (the paper's), ``"AKC+"`` (ours), ``"COIK"`` or the name of a corrector
            of your own (``MethodOptions.correctors``).
    """

    name: str
    occlusion: bool
    filter: str
    corrector: str


def parse_method(name: str, correctors: Iterable[str] = ()) -> MethodSpec:
    """The :class:`MethodSpec` of a method name.

    Args:
        name: one of :data:`METHODS`, or ``NAME(KF)`` / ``NAME(EKF)`` for a name in ``correctors``.
        correctors: the names of correctors of your own (``MethodOptions.correctors``).

    Raises:
        ValueError: naming the method when it is none of these.
    """
    if not isinstance(name, str):
        raise ValueError(f"method must be a string, got {name!r}")
    key = name.strip()
    if key == "Raw":
        return MethodSpec("Raw", False, "none", "none")
    if key in ("KF", "EKF"):
        return MethodSpec(key, True, key, "none")
    m = _PATTERN.match(key)
    if m and (m.group(1) in _CORRECTORS[1:] or m.group(1) in correctors):
        return MethodSpec(f"{m.group(1)}({m.group(2)})", True, m.group(2), m.group(1))
    own = "".join(f", {c}(KF), {c}(EKF)" for c in correctors)
    hint = f" (a corrector of your own: --add-corrector {m.group(1)}=FILE.py:FACTORY)" if m else ""
    raise ValueError(f"unknown method {name!r}; known: {', '.join(METHODS)}{own}{hint}")


def parse_methods(text: str | Iterable[str], correctors: Iterable[str] = ()) -> tuple[str, ...]:
    """Parse a comma-separated method list (``"Raw,KF,AKC(KF)"``) into canonical names, in order
    (``correctors``: as :func:`parse_method`).

    Raises:
        ValueError: naming the unknown method, or when the list is empty or repeats a method.
    """
    items = [s for s in (text.split(",") if isinstance(text, str) else text)]
    names = [parse_method(s, correctors).name for s in items if str(s).strip()]
    if not names:
        raise ValueError(f"--methods: no method given (known: {', '.join(METHODS)})")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"--methods: {', '.join(dup)} given more than once")
    return tuple(names)


@dataclass
class MethodResult:
    """One method's output over a session.

    Attributes:
        name: the method.
        estimates: ``(T, 12, 3)`` the pose after the method's last stage (NaN where it has none).
        stage_time_s: per stage name (see :data:`STAGES`), ``(T,)`` seconds each frame spent in it.
            Only the stages the method uses are present; ``"source"`` (S1 + S2) is the session's.
        status: for COIK, ``(T,)`` the solver status per frame ("success", "iteration_limit", ...);
            for AKC, ``(T,)`` "fallback" where the eq. (9) projection was used, else "ok"; None otherwise.
    """

    name: str
    estimates: np.ndarray
    stage_time_s: dict[str, np.ndarray] = field(default_factory=dict)
    status: np.ndarray | None = None

    def processing_time_s(self) -> np.ndarray:
        """``(T,)`` time of the method's own stages (everything but the source)."""
        parts = [v for k, v in self.stage_time_s.items() if k != "source"]
        if not parts:
            return np.zeros(self.estimates.shape[0])
        return np.sum(parts, axis=0)

    def total_time_s(self) -> np.ndarray:
        """``(T,)`` time of the whole chain per frame, source included (NaN when the source's is unknown)."""
        return self.processing_time_s() + self.stage_time_s.get(
            "source", np.full(self.estimates.shape[0], np.nan)
        )


# ---------------------------------------------------------------------------------------------- stages
def _occlusion_pass(session: Session, visibility_threshold: float, proximity: float, rules=None):
    from akc_drake.core.occlusion import occlusion_filter

    T = session.num_frames
    out = np.empty((T, NUM_LANDMARKS, 3))
    dt = np.empty(T)
    held = np.full((NUM_LANDMARKS, 3), np.nan)  # (the filter's state: each landmark's last accepted position)
    width = session.intrinsics.width
    clock = time.perf_counter
    for k in range(T):
        t0 = clock()
        res = occlusion_filter(
            session.raw[k],
            session.pixels[k],
            session.visibility[k],
            width,
            visibility_threshold=visibility_threshold,
            proximity=proximity,
            held=held,
            **(rules or {}),
        )
        dt[k] = clock() - t0
        out[k] = res[0] if isinstance(res, tuple) else res
    return out, dt


def make_filter(kind: str, dims: BodyDimensions | None, kf_config=None, ekf_config=None, ekf_kind="coupled"):
    """A fresh core filter: ``ConstantVelocityKF`` for ``"KF"``; for ``"EKF"`` our coupled
    ``ExtendedKalmanFilterCV`` (``ekf_kind="coupled"``) or the paper's ``PerJointEKF`` (``"per_joint"``)."""
    from akc_drake.core import ekf as ekf_mod
    from akc_drake.core import kalman

    if kind == "EKF" and ekf_kind == "per_joint":
        if dims is None:
            raise ValueError("the EKF needs body dimensions (dims)")
        return ekf_mod.PerJointEKF(dims, ekf_config)

    if kind == "KF":
        return (
            kalman.ConstantVelocityKF(config=kf_config)
            if kf_config is not None
            else kalman.ConstantVelocityKF()
        )
    if kind == "EKF":
        if dims is None:
            raise ValueError("the EKF needs body dimensions (dims)")
        if ekf_config is not None:
            return kalman.ExtendedKalmanFilterCV(dims, ekf_config)
        return kalman.ExtendedKalmanFilterCV(dims)
    raise ValueError(f"unknown filter {kind!r}; known: KF, EKF")


def run_filter(filt, measurements: np.ndarray, t: np.ndarray, variance: np.ndarray | None = None,
               taken: np.ndarray | None = None):
    """Run a core filter over ``measurements`` ``(T, 12, 3)`` at times ``t``.

    Args:
        filt: a core filter (``step``, ``reset``, ``position_variance``).
        measurements: ``(T, 12, 3)``, NaN where missing.
        t: ``(T,)`` seconds.
        variance: an optional ``(T, 12, 3)`` array that receives the filter's posterior variance of each
            coordinate after every step (read outside the timed step).
        taken: an optional ``(T, 12, 3)`` array that receives each frame's measurement as the filter took it
            (:func:`~akc_drake.core.landmark_tracking.taken_measurement`: NaN where its gate rejected a reading;
            without a gate, ``measurements``).

    Returns:
        ``(estimates (T, 12, 3), seconds per frame (T,))``.
    """
    T = measurements.shape[0]
    out = np.empty((T, NUM_LANDMARKS, 3))
    dt_run = np.empty(T)
    steps = np.diff(t, prepend=t[0] - (t[1] - t[0] if T > 1 else 0.1))
    filt.reset()
    clock = time.perf_counter
    for k in range(T):
        t0 = clock()
        est = filt.step(measurements[k], float(steps[k]))
        dt_run[k] = clock() - t0
        out[k] = est
        if variance is not None:
            variance[k] = filt.position_variance
        if taken is not None:
            taken[k] = taken_measurement(filt, measurements[k])
    return out, dt_run


def run_akc(corrector, poses: np.ndarray, measured: np.ndarray | None = None, variance: np.ndarray | None = None):
    """Run an AKC, AKC+ or your own corrector over ``poses`` ``(T, 12, 3)``; (corrected, seconds, status).

    ``measured`` ``(T, 12, 3)`` is the occlusion filter's output and ``variance`` ``(T, 12, 3)`` the filter's
    posterior variance, both given to AKC+ (which keeps the depths they show trustworthy).
    """
    T = poses.shape[0]
    out = np.empty((T, NUM_LANDMARKS, 3))
    dt_run = np.empty(T)
    status = np.empty(T, dtype="<U16")
    if hasattr(corrector, "reset"):
        corrector.reset()
    clock = time.perf_counter
    for k in range(T):
        t0 = clock()
        if measured is None:
            res = corrector.correct(poses[k])
        elif variance is None:
            res = corrector.correct(poses[k], measured[k])
        else:
            res = corrector.correct(poses[k], measured[k], variance[k])
        dt_run[k] = clock() - t0
        pose = getattr(res, "pose", res)  # (a corrector of your own may return the (12, 3) pose itself)
        if np.shape(pose) != (NUM_LANDMARKS, 3):  # (not broadcast: a (3,) or a scalar would fill every landmark)
            raise ValueError(f"{type(corrector).__name__}.correct returned a pose of shape {np.shape(pose)} at frame "
                             f"{k}, expected ({NUM_LANDMARKS}, 3)")
        out[k] = pose
        fb = getattr(res, "fallback", None)
        status[k] = "fallback" if fb is not None and bool(np.any(fb)) else "ok"
    return out, dt_run, status


def run_coik(solver, poses: np.ndarray):
    """Run a ``COIKSolver`` over ``poses`` ``(T, 12, 3)``; returns (corrected, seconds, status).

    The time is measured around the whole ``solve`` call (what the pipeline pays), not only the
    solver's own ``solve_time_s``.
    """
    T = poses.shape[0]
    out = np.empty((T, NUM_LANDMARKS, 3))
    dt_run = np.empty(T)
    status = np.empty(T, dtype="<U16")
    if hasattr(solver, "reset"):
        solver.reset()
    clock = time.perf_counter
    for k in range(T):
        t0 = clock()
        res = solver.solve(poses[k])
        dt_run[k] = clock() - t0
        out[k] = res.pose
        status[k] = str(res.status)
    return out, dt_run, status


# ---------------------------------------------------------------------------------------------- runner
@dataclass
class MethodOptions:
    """Settings shared by every method of one run.

    Attributes:
        visibility_threshold, proximity: the occlusion filter's (paper: 0.7 and 5 % of the width).
        kf_config, ekf_config: core filter configurations (None: the filters' defaults).
        ekf_kind: "coupled" (ours, :class:`~akc_drake.core.ekf.ExtendedKalmanFilterCV`) or "per_joint" (the
            paper's eq. 5, :class:`~akc_drake.core.ekf.PerJointEKF`).
        occlusion_rules: extra keyword arguments of the occlusion filter (None: ours; the paper's:
            :data:`akc_drake.core.occlusion.PAPER_RULES`).
        coik_config: COIK configuration (None: the solver's default).
        akc_plus_config: AKC+ settings: an ``AKCPlusConfig``, a dict of some of its fields (plain data, which
            crosses to the evaluation's workers) or None (the defaults).
        correctors: correctors of your own, name -> the import path of a factory (``"package.module:attribute"``;
            strings, so that they cross to the evaluation's workers, which import them), run as ``NAME(KF)`` and
            ``NAME(EKF)``: see :func:`load_corrector`.
    """

    visibility_threshold: float = 0.7
    proximity: float = 0.05
    kf_config: object | None = None
    ekf_config: object | None = None
    coik_config: object | None = None
    akc_plus_config: object | None = None
    ekf_kind: str = "coupled"
    occlusion_rules: dict | None = None
    correctors: dict | None = None


class MethodRunner:
    """Runs methods over one session, computing each shared stage prefix once.

    Args:
        session: the measurements.
        dims: calibrated body dimensions (for the EKF, AKC and COIK).
        weights: AKC weights (an ``AKCWeights``, a preset name "Wa" | "Wb" | "Wc", or None for the default).
        options: stage settings.
    """

    def __init__(
        self, session: Session, dims: BodyDimensions, weights=None, options: MethodOptions | None = None
    ):
        self.session = session
        self.dims = dims
        self.weights = resolve_weights(weights)
        self.options = options or MethodOptions()
        self._occ: tuple[np.ndarray, np.ndarray] | None = None
        self._filtered: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._variance: dict[str, np.ndarray] = {}
        self._taken: dict[str, np.ndarray] = {}
        self._done: dict[str, MethodResult] = {}
        self._own = dict(self.options.correctors or {})

    def occlusion(self) -> tuple[np.ndarray, np.ndarray]:
        """(accepted landmarks ``(T, 12, 3)``, seconds per frame) of the occlusion filter."""
        if self._occ is None:
            self._occ = _occlusion_pass(
                self.session, self.options.visibility_threshold, self.options.proximity,
                self.options.occlusion_rules,
            )
        return self._occ

    def filtered(self, kind: str) -> tuple[np.ndarray, np.ndarray]:
        """(output ``(T, 12, 3)``, seconds per frame) of filter ``kind`` on the occlusion filter's output."""
        if kind not in self._filtered:
            accepted, _ = self.occlusion()
            o = self.options
            filt = make_filter(kind, self.dims, o.kf_config, o.ekf_config, o.ekf_kind)
            var, taken = np.empty_like(accepted), np.empty_like(accepted)
            self._filtered[kind] = run_filter(filt, accepted, self.session.t, var, taken)
            self._variance[kind] = var
            self._taken[kind] = taken
        return self._filtered[kind]

    def taken(self, kind: str) -> np.ndarray:
        """``(T, 12, 3)`` the occlusion filter's output as filter ``kind`` took it (its gate's rejections NaN):
        what AKC+ and a corrector of your own are given as measured, as in the diagrams."""
        self.filtered(kind)
        return self._taken[kind]

    def filter_variance(self, kind: str) -> np.ndarray:
        """``(T, 12, 3)`` posterior variance of each coordinate of filter ``kind``'s output."""
        self.filtered(kind)
        return self._variance[kind]

    def run(self, name: str) -> MethodResult:
        """The result of method ``name`` (cached)."""
        spec = parse_method(name, self._own)
        if spec.name in self._done:
            return self._done[spec.name]
        s = self.session
        times: dict[str, np.ndarray] = {"source": s.source_time_s}
        status = None
        if spec.filter == "none":
            est = s.raw.copy()
        else:
            _, t_occ = self.occlusion()
            est, t_filt = self.filtered(spec.filter)
            times["occlusion"] = t_occ
            times["filter"] = t_filt
            if spec.corrector == "AKC":
                est, t_cor, status = run_akc(make_akc(self.dims, self.weights), est)
                times["corrector"] = t_cor
            elif spec.corrector == "AKC+":
                var = self.filter_variance(spec.filter)
                est, t_cor, status = run_akc(
                    make_akc_plus(self.dims, self.options.akc_plus_config, spec.filter, s.dt), est,
                    self.taken(spec.filter), var
                )
                times["corrector"] = t_cor
            elif spec.corrector == "COIK":
                est, t_cor, status = run_coik(make_coik(self.dims, self.options.coik_config), est)
                times["corrector"] = t_cor
            elif spec.corrector != "none":  # a corrector of your own: given what AKC+ is given
                factory = load_corrector(self._own[spec.corrector])
                est, t_cor, status = run_akc(
                    factory(self.dims, spec.filter, s.dt), est, self.taken(spec.filter),
                    self.filter_variance(spec.filter)
                )
                times["corrector"] = t_cor
        result = MethodResult(spec.name, est, times, status)
        self._done[spec.name] = result
        return result


def load_corrector(path: str) -> Callable:
    """The factory of a corrector of your own, from its import path ``"package.module:attribute"`` or a Python
    file's ``"path/to/file.py:attribute"``.

    The factory is called once per method and session as ``factory(dims, filter_kind, period_s)``: the calibrated
    :class:`~akc_drake.core.skeleton.BodyDimensions`, ``"KF"`` or ``"EKF"``, and the frame period in seconds. It
    returns an object with ``correct(pose, measured, variance)``, called every frame with the filter's ``(12, 3)``
    pose, the occlusion filter's ``(12, 3)`` measurement (NaN where a landmark or its depth was rejected) and the
    filter's ``(12, 3)`` posterior variance, in the camera frame, metres (the inputs AKC+ has). ``correct``
    returns the corrected ``(12, 3)`` pose, or an object with a ``pose`` attribute (an
    :class:`~akc_drake.core.akc.AKCResult`); ``reset()``, if the object has one, is called before each session.
    A class with ``__init__(self, dims, filter_kind, period_s)`` is such a factory.

    Raises:
        ValueError: the path is malformed, its module cannot be imported, or it names nothing callable.
    """
    module, sep, attr = str(path).rpartition(":")
    module, attr = module.strip(), attr.strip()
    if not sep or not module or not attr:
        raise ValueError(f"corrector {path!r}: expected package.module:attribute or file.py:attribute")
    if module.endswith(".py"):
        obj = _load_file(module, path)
    else:
        try:
            obj = importlib.import_module(module)
        except ImportError as e:
            raise ValueError(f"corrector {path!r}: cannot import {module!r} ({e})") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"corrector {path!r}: {module!r} has no {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"corrector {path!r}: {attr!r} is not callable")
    return obj


def _load_file(file: str, path: str):
    """The module of a Python file, loaded once per process (kept in ``sys.modules`` under a name made from its
    absolute path)."""
    f = Path(file).expanduser().resolve()
    if not f.is_file():
        raise ValueError(f"corrector {path!r}: no such file {file!r}")
    name = f"akc_drake_corrector_{f.stem}_{hashlib.sha1(str(f).encode()).hexdigest()[:8]}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, f)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
    except Exception as e:
        del sys.modules[name]
        raise ValueError(f"corrector {path!r}: {file!r} fails to load ({type(e).__name__}: {e})") from None
    return mod


def parse_correctors(text: str | Iterable[str]) -> dict[str, str]:
    """``NAME=package.module:attribute`` or ``NAME=file.py:attribute`` items, comma-separated (or a list of
    such strings) -> ``{NAME: path}`` (a file's path made absolute), each path loaded once here so that a wrong
    one fails before a long run (:func:`load_corrector`).

    Raises:
        ValueError: an item is malformed, a name is not a word (letters, digits, ``_+-``, a letter first) or is
            a built-in corrector's or repeated, or a path does not load.
    """
    items = [t for part in ([text] if isinstance(text, str) else text) for t in str(part).split(",") if t.strip()]
    out: dict[str, str] = {}
    for item in items:
        name, sep, path = item.partition("=")
        name, path = name.strip(), path.strip()
        if not sep or not name or not path:
            raise ValueError(f"corrector {item.strip()!r}: expected NAME=package.module:attribute")
        if not _LABEL.match(name):
            raise ValueError(f"corrector name {name!r}: letters, digits, '_', '+' and '-', a letter first")
        if name in _CORRECTORS or name in _FILTERS or name == "Raw":
            raise ValueError(f"corrector name {name!r} is a built-in method's")
        if name in out:
            raise ValueError(f"corrector name {name!r} given more than once")
        module, _, attr = path.rpartition(":")
        if module.strip().endswith(".py"):  # (absolute: a worker's working folder may differ)
            path = f"{Path(module.strip()).expanduser().resolve()}:{attr.strip()}"
        load_corrector(path)
        out[name] = path
    return out


def resolve_weights(weights):
    """An ``AKCWeights`` from an ``AKCWeights``, a preset name or None (the default, Wb)."""
    from akc_drake.core import akc

    if weights is None:
        return akc.AKCWeights()
    if isinstance(weights, str):
        try:
            return akc.WEIGHT_PRESETS[weights]
        except KeyError:
            raise ValueError(
                f"unknown AKC weight preset {weights!r}; known: {', '.join(akc.WEIGHT_PRESETS)}"
            ) from None
    if isinstance(weights, akc.AKCWeights):
        return weights
    raise ValueError(f"weights must be AKCWeights or a preset name, got {type(weights).__name__}")


def make_akc(dims: BodyDimensions, weights):
    """A fresh ``ArmKinematicCorrector``."""
    from akc_drake.core.akc import ArmKinematicCorrector

    return ArmKinematicCorrector(dims, resolve_weights(weights))


def make_akc_plus(dims: BodyDimensions, config=None, filter_kind: str | None = None, period_s: float | None = None):
    """A fresh ``ArmKinematicCorrectorPlus`` (AKC+). ``config``: an ``AKCPlusConfig``, a mapping of some of its
    fields, or None (:func:`~akc_drake.core.akc_plus_config.akc_plus_config`); ``filter_kind`` ("KF" | "EKF")
    sets a ``constrained_filter`` the config leaves at None (the EKFs' posteriors hold bone-length constraints);
    ``period_s``: the frame period its per-frame settings are scaled to (None: 10 Hz)."""
    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
    from akc_drake.core.akc_plus_config import akc_plus_config

    return ArmKinematicCorrectorPlus(dims, akc_plus_config(config, filter_kind), period_s)


def make_coik(dims: BodyDimensions, config=None):
    """A fresh ``COIKSolver`` (the program is built once per solver)."""
    from akc_drake.core.coik import COIKSolver

    return COIKSolver(dims, config) if config is not None else COIKSolver(dims)


def run_method(
    name: str,
    session: Session,
    dims: BodyDimensions,
    weights=None,
    options: MethodOptions | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Run one method over a session.

    Args:
        name: one of :data:`METHODS`.
        session: the measurements.
        dims: calibrated body dimensions.
        weights: AKC weights or preset name (AKC methods only).
        options: stage settings.

    Returns:
        ``(estimates (T, 12, 3), {stage: seconds per frame (T,)})``.
    """
    res = MethodRunner(session, dims, weights, options).run(name)
    return res.estimates, res.stage_time_s


def run_methods(
    names: Iterable[str],
    session: Session,
    dims: BodyDimensions,
    weights=None,
    options: MethodOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, MethodResult]:
    """Run several methods over one session, sharing stage prefixes; ``progress(name)`` after each."""
    runner = MethodRunner(session, dims, weights, options)
    out = {}
    for name in names:
        out[parse_method(name, runner.options.correctors or ()).name] = runner.run(name)
        if progress is not None:
            progress(name)
    return out
