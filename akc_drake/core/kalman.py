"""Constant-velocity Kalman filter (paper eq. 1-3) and the bone-length-constrained EKF (eq. 4-6).

Stage S3b of the pipeline. Every landmark ``p = [x, y, z]`` (camera frame C, metres) is tracked
with a constant-velocity model, state ``x_k = [p_k, p_dot_k]`` (eq. 1)::

    x_k = A x_{k-1} + w_k,    z_k = H x_k + v_k                                   (eq. 2)
    R = diag(sigma_x^2, sigma_y^2, sigma_z^2),    sigma_z >> sigma_x, sigma_y       (eq. 3)

with ``A = [[I, dt I], [0, I]]``, ``H = [I, 0]`` and the white-noise-acceleration process noise
``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` per axis (``q`` the acceleration spectral density).

**Decoupled KF.** With a diagonal ``R`` and a per-axis ``Q`` the 6-state filter of one landmark
splits exactly into three independent 2-state filters (position, velocity) along x, y and z.
:class:`ConstantVelocityKF` therefore keeps ``p, v, P_pp, P_pv, P_vv`` as rows of ``3 J`` numbers
and runs all ``3 J`` two-state filters at once: about fifteen whole-array numpy operations per
frame, no loop over landmarks. It is equal (to rounding) to the textbook 6-state filter with
full matrices; the tests check that to 1e-12.

**Constrained EKF.** :class:`ExtendedKalmanFilterCV` adds, after the measurement update, one
pseudo-measurement per connected pair (LUA, LLA, RUA, RLA, SW)::

    h(x) = |p_i - p_j| = l                                                         (eq. 4)
    H_c = [(p_i - p_j)^T / |p_i - p_j|, 0, 0, 0]  (and the negative for p_j)        (eq. 5)
    x <- x + K_c (l - h(x))                                                        (eq. 6)

with its own variance ``sigma_c^2``: a soft constraint toward the calibrated lengths. The six
arm landmarks (shoulders, elbows, wrists) are coupled through it and carry a full 36 x 36
covariance (plus, with ``EKFConfig.length_tau_s``, one state per segment for the persistent part of
its length error); the other six landmarks keep the decoupled KF.

**Missing data.** A measurement is a ``(J, 3)`` array with NaN where missing (the occlusion filter
drops a depth by setting only ``z`` to NaN). Each axis that is present is used: all three ->
full update; ``z`` missing -> the partial update of the paper with ``x`` and ``y`` only; nothing
-> prediction only. The first measurement of an axis initialises it (``p = z``, ``v = 0``,
``P = diag(r, init_vel_var)``); an axis that was never measured reads NaN.

**Losing a track.** An axis extrapolates for at most ``max_predict_s`` after its last
measurement; a prediction step that would take it beyond that is replaced by holding: the
velocity is zeroed (in the EKF also its covariance, every step) and the position no longer moves
by the motion model (the EKF's bone constraints may still correct it). A held axis's variance
keeps growing, up to :data:`MAX_HELD_POSITION_VAR` in the KF (in the EKF it grows only by the
process noise, about 1e-4 m^2 per 0.1 s step). The next measurement of a held axis
re-initialises it rather than being fused with the stale estimate. A landmark none of whose
axes has been measured for longer than ``max_predict_s`` has status :data:`LOST`.

**Innovation gate** (off by default). With ``gate_sigma`` set, a measured axis whose normalised
innovation ``|y| / sqrt(S)`` exceeds it is treated as missing; after ``gate_max_rejects``
consecutive rejections of the same axis the measurement is accepted and the axis re-initialised,
so the filter can never lock itself out of a track that really moved. With ``gate_whole_landmark``
one failing axis rejects the landmark's whole measurement (all three axes are one observation: a
detector jump or a bad depth moves them together), including an axis that would have been
re-initialised after being held.

All filter state lives in one flat float vector (:meth:`get_state_vector` /
:meth:`set_state_vector`) so a Drake context can carry it and a simulation can be replayed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, SEGMENT_NAMES, SEGMENTS

#: Tracking status codes (:attr:`ConstantVelocityKF.status`).
UNINITIALISED = 0
TRACKING = 1
PREDICTING = 2
LOST = 3
STATUS_NAMES: tuple[str, ...] = ("UNINITIALISED", "TRACKING", "PREDICTING", "LOST")
_STATUS_OF_BIN = np.array([TRACKING, PREDICTING, LOST, UNINITIALISED], dtype=np.int64)

#: Caps of a held (no longer extrapolated) axis's position variance (m^2: sigma 10 m, anywhere in the camera's
#: view) and velocity variance ((m/s)^2) in :class:`ConstantVelocityKF`.
MAX_HELD_POSITION_VAR = 100.0
MAX_HELD_VELOCITY_VAR = 100.0

# Slack on time comparisons: ages are sums of float periods (10 x 0.1 = 0.9999999999999999).
_T_EPS = 1e-9
# The EKF re-symmetrises its covariance every this many steps.
_SYMMETRISE_EVERY = 16


def _positive(name: str, value, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be a {kind} finite number, got {value!r}")
    return v


@dataclass(frozen=True)
class KFConfig:
    """Noise model and track management of the constant-velocity Kalman filter.

    Defaults are for an Intel RealSense D435 seeing the operator at about 2 m, 640x480, with a 2D
    landmark detector:

    * ``sigma_x = sigma_y = 0.01`` m: a 2D landmark jitters by about 3 px; at 2 m with
      ``fx = 615`` px one pixel is 3.3 mm.
    * ``sigma_z = 0.05`` m: the D435's depth RMS error is about 2 % of the range (4 cm at 2 m),
      and the depth is read on the body surface, not at the joint centre.
    * ``accel_psd = 0.3`` m^2/s^3 per axis: the paper's motions (6 s cycles with arm-length
      amplitudes) accelerate by about 0.5 m/s^2; 0.3 allows a velocity change of
      ``sqrt(q dt) = 0.17`` m/s per 10 Hz frame. On a simulated 6 s, 0.3 m sinusoid with these
      sigmas values between 0.05 and 0.5 give RMSEs within 15 % of each other; larger values
      follow faster motion with less lag, smaller ones smooth more.
    * ``init_vel_var = 0.25`` (m/s)^2: a new track's velocity is unknown to about 0.5 m/s.

    Attributes:
        sigma_x, sigma_y, sigma_z: measurement standard deviations in metres (eq. 3).
        accel_psd: white-noise acceleration spectral density ``q`` per axis (x, y, z), m^2/s^3.
        init_vel_var: variance of the velocity of a newly initialised axis, (m/s)^2.
        max_predict_s: longest extrapolation after an axis's last measurement, seconds; ``math.inf`` is the
            paper's filter, which never holds (a lost depth drifts at its last velocity).
        gate_sigma: innovation gate in standard deviations, or None (default) for no gate.
        gate_max_rejects: consecutive gate rejections after which a measurement is accepted and
            the axis re-initialised.
        gate_whole_landmark: an axis failing the gate rejects all axes of its landmark.
        gate_speed_m_s: with the gate, an innovation no larger than this speed times the time since the axis
            was last measured always passes, None (default) for no such floor. The white-noise acceleration
            above is the paper's slow motions' (0.5 m/s^2); real arms accelerate far more, and a gate in its
            standard deviations alone rejects them: on the 10 real motion-capture clips (``evaluate
            --motion-dir``, the teleop diagram's 0.3 s prediction), a 5-sigma whole-landmark gate took the KF's
            mean 3D arm RMSE from 4.5 to 11.5 cm (simulated detector; 12 sigma: 6.9). A detector's jump across
            the image or a depth read on the background is further than a body moves (the teleop diagram's
            6 m/s: 60 cm in a 10 Hz frame, ``akc_drake.config.TELEOP_GATE_SPEED_M_S``).
    """

    sigma_x: float = 0.01
    sigma_y: float = 0.01
    sigma_z: float = 0.05
    accel_psd: tuple[float, float, float] = (0.3, 0.3, 0.3)
    init_vel_var: float = 0.25
    max_predict_s: float = 1.0
    gate_sigma: float | None = None
    gate_max_rejects: int = 5
    gate_whole_landmark: bool = False
    gate_speed_m_s: float | None = None

    def __post_init__(self):
        cls = type(self).__name__
        for name in ("sigma_x", "sigma_y", "sigma_z", "init_vel_var"):
            object.__setattr__(self, name, _positive(f"{cls}.{name}", getattr(self, name)))
        # max_predict_s may be inf: the paper's KF, which extrapolates a lost axis for ever (no hold).
        mp = self.max_predict_s
        if mp != math.inf:
            mp = _positive(f"{cls}.max_predict_s", mp)
        object.__setattr__(self, "max_predict_s", float(mp))
        q = self.accel_psd
        if isinstance(q, (int, float, np.integer, np.floating)):
            q = (q, q, q)
        try:
            q = tuple(q)
        except TypeError:
            raise ValueError(f"{cls}.accel_psd must be 3 numbers (x, y, z), got {self.accel_psd!r}") from None
        if len(q) != 3:
            raise ValueError(f"{cls}.accel_psd must be 3 numbers (x, y, z), got {self.accel_psd!r}")
        q = tuple(_positive(f"{cls}.accel_psd[{i}]", qi, allow_zero=True) for i, qi in enumerate(q))
        object.__setattr__(self, "accel_psd", q)
        if self.gate_sigma is not None:
            object.__setattr__(self, "gate_sigma", _positive(f"{cls}.gate_sigma", self.gate_sigma))
        if self.gate_speed_m_s is not None:
            object.__setattr__(self, "gate_speed_m_s", _positive(f"{cls}.gate_speed_m_s", self.gate_speed_m_s))
        g = self.gate_max_rejects
        if isinstance(g, bool) or not isinstance(g, (int, np.integer)) or g < 1:
            raise ValueError(f"{cls}.gate_max_rejects must be an integer >= 1, got {g!r}")

    @property
    def r(self) -> np.ndarray:
        """Measurement variances ``(3,)``: the diagonal of R (eq. 3)."""
        return np.array([self.sigma_x, self.sigma_y, self.sigma_z]) ** 2


@dataclass(frozen=True)
class EKFConfig(KFConfig):
    """:class:`KFConfig` plus the bone-length constraint of the EKF (eq. 4-6).

    Attributes:
        sigma_c: standard deviation of the bone-length pseudo-measurement, metres: its part that is new
            every frame. 0.01 m: about the accuracy of a T-pose calibration; smaller values hold the
            lengths harder.
        segments: which segments are constrained (names of ``skeleton.SEGMENTS``).
        length_tau_s: correlation time (s) of the persistent part of each segment's length error in our
            coupled EKF (:class:`~akc_drake.core.ekf.ExtendedKalmanFilterCV`), or None: no persistent part
            (the white pseudo-measurement of eq. 4-6 alone). The distance between two detected landmarks
            differs from the calibrated length by an error that persists from frame to frame: the
            calibration's own error, and landmarks that move on the body with the pose. Taken as fresh
            evidence every frame, the same error makes the filter ever more certain of a wrong depth (on
            the rendered bench the coupled EKF's depth was 2-3 times worse than its variance said). With
            ``length_tau_s`` each segment carries a first-order Gauss-Markov deviation state ``b`` and the
            pseudo-measurement is ``|p_i - p_j| = l + b`` (white part ``sigma_c``). 3 s: about as long as an
            arm holds one posture (the paper's motions are 6 s cycles); 1 s and 10 s give nearly the same
            results on the bench and the real clips. The paper's per-joint EKF
            (:class:`~akc_drake.core.ekf.PerJointEKF`) ignores this and the two sigmas below.
        length_sigma_m: stationary standard deviation of an arm bone's ``b`` (m): a T-pose calibration's
            accuracy, 0.01.
        width_sigma_m: stationary standard deviation of the shoulder width's ``b`` (m). The shoulder width is
            not a bone: the shoulders ride on the shoulder girdle, which protracts, retracts and rises with
            the arms, and a detected shoulder landmark moves with it (on the bench, the detected shoulders
            are on average 1.6 cm (Motion I) and 4.2 cm (Motion II) closer in the image than the calibrated
            width, mostly where their depth is dropped). With the torso facing the camera the width lies in the
            image plane, where a length says little about depth and a few cm of it become a large depth
            difference (``sqrt(l^2 - d_xy^2)``). 0.03 (the bench gives the same with 0.05; with 0.01 the
            Motion I shoulders are 4.0 cm instead of 2.7).
    """

    sigma_c: float = 0.01
    segments: tuple[str, ...] = SEGMENT_NAMES
    length_tau_s: float | None = 3.0
    length_sigma_m: float = 0.01
    width_sigma_m: float = 0.03

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "sigma_c", _positive("EKFConfig.sigma_c", self.sigma_c))
        if self.length_tau_s is not None:
            object.__setattr__(self, "length_tau_s", _positive("EKFConfig.length_tau_s", self.length_tau_s))
        for name in ("length_sigma_m", "width_sigma_m"):
            object.__setattr__(self, name, _positive(f"EKFConfig.{name}", getattr(self, name)))
        segs = (self.segments,) if isinstance(self.segments, str) else tuple(self.segments)
        unknown = [s for s in segs if s not in SEGMENTS]
        if unknown or not segs or len(set(segs)) != len(segs):
            known = ", ".join(SEGMENT_NAMES)
            raise ValueError(f"EKFConfig.segments must be distinct names from {known}, got {self.segments!r}")
        object.__setattr__(self, "segments", segs)

    def kf_config(self) -> KFConfig:
        """The plain :class:`KFConfig` part."""
        return KFConfig(**{f.name: getattr(self, f.name) for f in fields(KFConfig)})


def _check_dt(dt) -> float:
    try:
        d = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}") from None
    if not (0.0 < d < math.inf):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    return d


def _check_z(z, shape: tuple[int, int]) -> np.ndarray:
    a = np.asarray(z, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"measurement z must have shape {shape}, got {a.shape}")
    return a


def _process_noise(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]] per axis: the (pp, pv, vv) entries, each ``(3,)``."""
    return q * (dt**3 / 3.0), q * (dt**2 / 2.0), q * dt


def status_from(initialised: np.ndarray, age: np.ndarray, max_predict_s: float) -> np.ndarray:
    """Per-landmark status from which axes are initialised ``(J, 3)`` bool and their ages ``(J, 3)``.

    Returns:
        ``(J,)`` int: :data:`UNINITIALISED` if no axis was ever measured, :data:`TRACKING` if an
        axis was measured at the last step, :data:`LOST` if no axis has been measured for longer
        than ``max_predict_s``, :data:`PREDICTING` otherwise.
    """
    # Age of each landmark's most recent measurement (inf if never measured), binned:
    # (-inf, 0] TRACKING, (0, max] PREDICTING, (max, 1e300] LOST, inf UNINITIALISED.
    newest = np.where(initialised, age, np.inf).min(axis=1)
    bins = np.array([0.0, min(max_predict_s + _T_EPS, 1e299), 1e300])
    return _STATUS_OF_BIN[np.searchsorted(bins, newest)]


def _gate(cfg: KFConfig, use, y, S, rejects, reinit, elapsed):
    """Innovation gate on the axes ``use`` (bool, updated in place together with ``reinit``).

    ``y`` are the innovations and ``S`` their variances (same shape); ``elapsed`` the time since each axis was
    last measured, this step included (for ``gate_speed_m_s``). Returns nothing; ``rejects`` counts consecutive
    rejections per axis.
    """
    g = cfg.gate_sigma
    with np.errstate(invalid="ignore"):
        bad = use & (y * y > (g * g) * S)
        v = cfg.gate_speed_m_s
        if v is not None and bad.any():
            bad &= np.abs(y) > v * elapsed
    if cfg.gate_whole_landmark and bad.any():
        # One observation per landmark: reject all of its measured axes, those to re-initialise too.
        bad = np.repeat(bad.reshape(-1, 3).any(axis=1), 3) & (use | reinit)
        reinit &= ~bad
    rejects[use & ~bad] = 0.0
    rejects[bad] += 1.0
    force = bad & (rejects >= cfg.gate_max_rejects)
    rejects[force] = 0.0
    reinit |= force
    use &= ~bad


class ConstantVelocityKF:
    """Constant-velocity Kalman filter for ``J`` landmarks (eq. 1-3), vectorised over axes.

    Args:
        num_landmarks: number of landmarks ``J`` (12 for the pipeline).
        config: noise model and track management.

    Each of the ``3 J`` axes is an independent 2-state filter (exact for diagonal R and per-axis
    Q, see the module docstring). Internally every quantity is a contiguous row of ``3 J`` floats
    (landmark-major, x/y/z innermost) of one ``(8, 3 J)`` buffer with rows
    ``[p, v, P_pp, P_pv, P_vv, age, initialised, rejects]`` (``p`` is 0, not NaN, on uninitialised
    axes so that the matrix product of the prediction never meets a NaN). A step is about fifteen
    numpy operations on whole rows (the prediction, ageing included, is one 6 x 6 matrix product).
    """

    _P, _V, _PPP, _PPV, _PVV, _AGE, _INIT, _REJ = range(8)

    def __init__(self, num_landmarks: int = NUM_LANDMARKS, config: KFConfig | None = None):
        bad = isinstance(num_landmarks, bool) or not isinstance(num_landmarks, (int, np.integer))
        if bad or num_landmarks < 1:
            raise ValueError(f"num_landmarks must be a positive integer, got {num_landmarks!r}")
        config = KFConfig() if config is None else config
        if not isinstance(config, KFConfig):
            raise ValueError(f"config must be a KFConfig, got {type(config).__name__}")
        self.num_landmarks = J = int(num_landmarks)
        self.config = config
        self._shape = (J, 3)
        N = 3 * J
        self._r = np.tile(config.r, J)
        self._q = np.tile(np.array(config.accel_psd, dtype=np.float64), J)
        self._limit = config.max_predict_s + _T_EPS
        self._s = s = np.empty((8, N))
        self._p, self._v, self._Ppp, self._Ppv, self._Pvv, self._age, self._init, self._rej = s
        self._p_v = s[0:2]
        self._Ppp_Ppv = s[2:4]
        self._first6 = s[:6]
        # Prediction: rows 0..5 <- L @ rows 0..5 + Q (L and Q set with dt), and scratch arrays.
        self._L = np.eye(6)
        self._Q = np.zeros((6, N))
        self._T6 = np.empty((6, N))
        self._t = np.empty(N)
        self._S = np.empty(N)
        self._y = np.empty(N)
        self._T2 = np.empty((2, N))
        self._K = np.empty((2, N))
        self._dt = None
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def state_size(self) -> int:
        """Length of :meth:`get_state_vector`."""
        return self._s.size

    def reset(self) -> None:
        """Forget every track (all landmarks back to UNINITIALISED)."""
        self._s[...] = 0.0
        self._all_init = False
        self._oldest = 0.0

    def get_state_vector(self) -> np.ndarray:
        """All filter state as a new 1-D float array."""
        return self._s.flatten()

    def set_state_vector(self, v) -> None:
        """Load the state written by :meth:`get_state_vector` (of a filter with the same size)."""
        a = np.asarray(v, dtype=np.float64).reshape(-1)
        if a.size != self._s.size:
            raise ValueError(f"state vector must have {self._s.size} entries, got {a.size}")
        self._s.reshape(-1)[...] = a
        self._all_init = bool(self._init.all())
        self._oldest = float(self._age.max())

    def _view(self, row: np.ndarray, nan_uninit: bool) -> np.ndarray:
        out = row.reshape(self._shape).copy()
        if nan_uninit and not self._all_init:
            out[self._init.reshape(self._shape) == 0.0] = np.nan
        return out

    @property
    def initialised(self) -> np.ndarray:
        """``(J, 3)`` bool: the axis has been measured at least once."""
        return self._init.reshape(self._shape) != 0.0

    @property
    def position(self) -> np.ndarray:
        """Estimated positions ``(J, 3)``, NaN for axes never measured."""
        return self._view(self._p, True)

    @property
    def velocity(self) -> np.ndarray:
        """Estimated velocities ``(J, 3)`` (m/s), NaN for axes never measured."""
        return self._view(self._v, True)

    @property
    def position_variance(self) -> np.ndarray:
        """Variance of each position axis ``(J, 3)``, NaN for axes never measured."""
        return self._view(self._Ppp, True)

    @property
    def axis_age(self) -> np.ndarray:
        """Seconds since each axis was last measured ``(J, 3)`` (0 for axes never measured)."""
        return self._view(self._age, False)

    @property
    def status(self) -> np.ndarray:
        """``(J,)`` int: 0 UNINITIALISED, 1 TRACKING, 2 PREDICTING, 3 LOST."""
        return status_from(self.initialised, self._age.reshape(self._shape), self.config.max_predict_s)

    # ------------------------------------------------------------------ step
    def _set_dt(self, dt: float) -> None:
        P, V, PPP, PPV, PVV, AGE = self._P, self._V, self._PPP, self._PPV, self._PVV, self._AGE
        Q = self._Q
        Q[PPP], Q[PPV], Q[PVV] = _process_noise(self._q, dt)
        Q[AGE] = dt
        L = self._L
        L[P, V] = dt  # p += dt v
        L[PPP, PPV] = 2.0 * dt  # P_pp += 2 dt P_pv + dt^2 P_vv
        L[PPP, PVV] = dt * dt
        L[PPV, PVV] = dt  # P_pv += dt P_vv
        self._dt = dt

    def step(self, z, dt: float) -> np.ndarray:
        """Advance by ``dt`` seconds and fuse measurement ``z``.

        Args:
            z: ``(J, 3)`` measured positions, NaN where missing.
            dt: time since the previous step, seconds (> 0).

        Returns:
            ``(J, 3)`` estimated positions (a new array), NaN only for axes never measured.

        Raises:
            ValueError: ``z`` has the wrong shape or ``dt`` is not positive.
        """
        return self._step(_check_z(z, self._shape).reshape(-1), _check_dt(dt))

    def _step(self, z: np.ndarray, dt: float) -> np.ndarray:
        """:meth:`step` on a checked flat ``z`` (3 J,) and ``dt``."""
        if dt != self._dt:
            self._set_dt(dt)
        p, age = self._p, self._age
        m = np.isfinite(z)
        # Track management only when some axis is uninitialised or may pass max_predict_s this step
        # (``_oldest`` is an upper bound of the oldest axis age).
        limit = self._limit
        slow = not self._all_init or self._oldest + dt > limit
        if slow:
            # Unmeasured axes whose extrapolation would go beyond max_predict_s stop (v = 0); this
            # also covers axes already LOST. Their covariance keeps growing, unused (their next
            # measurement re-initialises them), up to the caps below.
            held = (age > limit - dt) & ~m
            np.copyto(self._v, 0.0, where=held)
            reinit = m & (age > limit)
            if not self._all_init:
                reinit |= m & (self._init == 0.0)
            use = m & ~reinit
        else:
            use = m

        # eq. (2), prediction x = A x, P = A P A^T + Q for every axis at once, as one linear map
        # of the rows: p += dt v; P_pp += 2 dt P_pv + dt^2 P_vv; P_pv += dt P_vv; + Q; age += dt.
        np.dot(self._L, self._first6, out=self._T6)
        np.add(self._T6, self._Q, out=self._first6)
        if slow and held.any():
            # A held axis's uncertainty grows (P_pp like t^3) but is capped, so that a landmark that never
            # comes back (hips out of the frame for a whole session) keeps a bounded covariance.
            np.minimum(self._Ppp, MAX_HELD_POSITION_VAR, out=self._Ppp, where=held)
            np.minimum(self._Pvv, MAX_HELD_VELOCITY_VAR, out=self._Pvv, where=held)
            bound = np.sqrt(self._Ppp * self._Pvv)
            np.clip(self._Ppv, -bound, bound, out=self._Ppv, where=held)

        # eq. (3), measurement update of the measured axes only (``where=use``): the partial
        # update when only x, y are present.
        # S = H P H^T + R (a scalar per axis)
        S = np.add(self._Ppp, self._r, out=self._S)
        # y = z - H x
        y = np.subtract(z, p, out=self._y)
        if self.config.gate_sigma is not None:
            if not slow:
                reinit = np.zeros_like(m)
                slow = True
            _gate(self.config, use, y, S, self._rej, reinit, age)
        # K = P H^T S^-1 = [P_pp, P_pv] / S
        K = np.divide(self._Ppp_Ppv, S, out=self._K)
        # x = x + K y
        T2 = np.multiply(K, y, out=self._T2)
        np.add(self._p_v, T2, out=self._p_v, where=use)
        # P = (I - K H) P:  P_vv -= K_v P_pv;  [P_pp, P_pv] -= K_p [P_pp, P_pv]
        t = np.multiply(K[1], self._Ppv, out=self._t)
        np.subtract(self._Pvv, t, out=self._Pvv, where=use)
        np.multiply(self._Ppp_Ppv, K[0], out=T2)
        np.subtract(self._Ppp_Ppv, T2, out=self._Ppp_Ppv, where=use)

        if slow:
            if reinit.any():
                p[reinit] = z[reinit]
                self._v[reinit] = 0.0
                self._Ppp[reinit] = self._r[reinit]
                self._Ppv[reinit] = 0.0
                self._Pvv[reinit] = self.config.init_vel_var
                self._rej[reinit] = 0.0
                use |= reinit
            if not self._all_init:
                self._init[reinit] = 1.0
                age[self._init == 0.0] = 0.0
                self._all_init = bool(self._init.all())
        age[use] = 0.0
        # Refresh the bound on the oldest age only when it matters.
        self._oldest += dt
        if self._oldest + dt > limit:
            self._oldest = float(age.max())
        if self._all_init:
            return p.reshape(self._shape).copy()
        return np.where(self._init == 0.0, np.nan, p).reshape(self._shape)


#: Row permutation of a ``(12, 3)`` pose that exchanges every left landmark with its right counterpart.
LEFT_RIGHT_SWAP: np.ndarray = np.array(
    [INDEX[n.replace("left_", "right_") if n.startswith("left_") else n.replace("right_", "left_")]
     for n in INDEX],
    dtype=np.intp,
)


#: How much better a swapped labelling must fit, and the left/right pairs it needs (:func:`left_right_swapped`).
SWAP_RATIO, SWAP_MIN_PAIRS = 0.25, 2


def left_right_swapped(z, predicted, *, ratio: float = SWAP_RATIO, min_pairs: int = SWAP_MIN_PAIRS) -> bool:
    """Whether the detector swapped the person's left and right in measurement ``z``.

    A 2D pose detector sometimes labels a whole body mirror-wise for a frame. Compared with the filter's
    prediction, the swapped labelling then fits far better: the sum of squared distances of the landmarks
    measured in ``z`` to ``predicted`` drops below ``ratio`` times the sum as labelled when ``z``'s left and
    right are exchanged. Shoulders and hips, which never cross, decide it when the hands are close together.

    Args:
        z: ``(12, 3)`` measured landmarks (NaN where missing).
        predicted: ``(12, 3)`` the filter's prediction for the same instant (NaN where unknown).
        ratio: how much better the swapped labelling must fit.
        min_pairs: left/right pairs that must be measured and predicted on both sides.

    Returns:
        True when ``z`` should be read with left and right exchanged (``z[LEFT_RIGHT_SWAP]``).
    """
    z = np.asarray(z, dtype=np.float64)
    pred = np.asarray(predicted, dtype=np.float64)
    zs = z[LEFT_RIGHT_SWAP]
    d_given = z - pred
    d_swap = zs - pred
    both = np.isfinite(d_given) & np.isfinite(d_swap)
    pairs = both.all(axis=1) & both.all(axis=1)[LEFT_RIGHT_SWAP]
    if int(pairs.sum()) < 2 * min_pairs:
        return False
    e_given = float(np.square(d_given[pairs]).sum())
    e_swap = float(np.square(d_swap[pairs]).sum())
    return e_swap < ratio * e_given


def __getattr__(name: str):
    """The EKFs live in :mod:`akc_drake.core.ekf`; ``kalman.ExtendedKalmanFilterCV`` keeps working."""
    if name in ("ExtendedKalmanFilterCV", "PerJointEKF"):
        from akc_drake.core import ekf

        return getattr(ekf, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
