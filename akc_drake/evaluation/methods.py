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

The stages are the core objects the Drake LeafSystems wrap, called directly frame by frame, so the
accuracy and the speed measured here are those of the code the diagram runs. Shared prefixes are
computed once (:class:`MethodRunner`): AKC(KF) and COIK(KF) see exactly the same KF output, which is
both fair and fast. Every stage is timed per frame with ``time.perf_counter``.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

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
_PATTERN = re.compile(r"^\s*(AKC\+|AKC|COIK)\s*\(\s*(KF|EKF)\s*\)\s*$")


@dataclass(frozen=True)
class MethodSpec:
    """What a method is made of.

    Attributes:
        name: the canonical name (e.g. ``"AKC(KF)"``).
        occlusion: whether the occlusion filter runs first.
        filter: ``"none"``, ``"KF"`` or ``"EKF"``.
        corrector: ``"none"``, ``"AKC"`` (the paper's), ``"AKC+"`` (ours) or ``"COIK"``.
    """

    name: str
    occlusion: bool
    filter: str
    corrector: str


def parse_method(name: str) -> MethodSpec:
    """The :class:`MethodSpec` of a method name.

    Raises:
        ValueError: naming the method when it is not one of :data:`METHODS`.
    """
    if not isinstance(name, str):
        raise ValueError(f"method must be a string, got {name!r}")
    key = name.strip()
    if key == "Raw":
        return MethodSpec("Raw", False, "none", "none")
    if key in ("KF", "EKF"):
        return MethodSpec(key, True, key, "none")
    m = _PATTERN.match(key)
    if m:
        return MethodSpec(f"{m.group(1)}({m.group(2)})", True, m.group(2), m.group(1))
    raise ValueError(f"unknown method {name!r}; known: {', '.join(METHODS)}")


def parse_methods(text: str | Iterable[str]) -> tuple[str, ...]:
    """Parse a comma-separated method list (``"Raw,KF,AKC(KF)"``) into canonical names, in order.

    Raises:
        ValueError: naming the unknown method, or when the list is empty or repeats a method.
    """
    items = [s for s in (text.split(",") if isinstance(text, str) else text)]
    names = [parse_method(s).name for s in items if str(s).strip()]
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


def run_filter(filt, measurements: np.ndarray, t: np.ndarray, variance: np.ndarray | None = None):
    """Run a core filter over ``measurements`` ``(T, 12, 3)`` at times ``t``.

    Args:
        filt: a core filter (``step``, ``reset``, ``position_variance``).
        measurements: ``(T, 12, 3)``, NaN where missing.
        t: ``(T,)`` seconds.
        variance: an optional ``(T, 12, 3)`` array that receives the filter's posterior variance of each
            coordinate after every step (read outside the timed step).

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
    return out, dt_run


def run_akc(corrector, poses: np.ndarray, measured: np.ndarray | None = None, variance: np.ndarray | None = None):
    """Run an AKC or AKC+ corrector over ``poses`` ``(T, 12, 3)``; (corrected, seconds, status).

    ``measured`` ``(T, 12, 3)`` is the occlusion filter's output and ``variance`` ``(T, 12, 3)`` the filter's
    posterior variance, both given to AKC+ (which keeps the depths they show trustworthy).
    """
    T = poses.shape[0]
    out = np.empty((T, NUM_LANDMARKS, 3))
    dt_run = np.empty(T)
    status = np.empty(T, dtype="<U16")
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
        out[k] = res.pose
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
    """

    visibility_threshold: float = 0.7
    proximity: float = 0.05
    kf_config: object | None = None
    ekf_config: object | None = None
    coik_config: object | None = None
    akc_plus_config: object | None = None
    ekf_kind: str = "coupled"
    occlusion_rules: dict | None = None


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
        self._done: dict[str, MethodResult] = {}

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
            var = np.empty_like(accepted)
            self._filtered[kind] = run_filter(filt, accepted, self.session.t, var)
            self._variance[kind] = var
        return self._filtered[kind]

    def filter_variance(self, kind: str) -> np.ndarray:
        """``(T, 12, 3)`` posterior variance of each coordinate of filter ``kind``'s output."""
        self.filtered(kind)
        return self._variance[kind]

    def run(self, name: str) -> MethodResult:
        """The result of method ``name`` (cached)."""
        spec = parse_method(name)
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
                accepted, _ = self.occlusion()
                var = self.filter_variance(spec.filter)
                est, t_cor, status = run_akc(
                    make_akc_plus(self.dims, self.options.akc_plus_config, spec.filter, s.dt), est, accepted, var
                )
                times["corrector"] = t_cor
            elif spec.corrector == "COIK":
                est, t_cor, status = run_coik(make_coik(self.dims, self.options.coik_config), est)
                times["corrector"] = t_cor
        result = MethodResult(spec.name, est, times, status)
        self._done[spec.name] = result
        return result


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
        out[parse_method(name).name] = runner.run(name)
        if progress is not None:
            progress(name)
    return out
