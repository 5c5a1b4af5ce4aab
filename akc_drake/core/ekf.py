"""The EKFs of stage S3b: the paper's per-joint EKF (eq. 4-6) and our coupled bone-length EKF.

Both add bone-length pseudo-measurements ``h(x) = |p_i - p_j| = l`` (eq. 4) to the constant-velocity model
of :mod:`akc_drake.core.kalman` (which documents the model, missing data, holding and the gate):

* :class:`PerJointEKF` (``--protocol paper``): eq. (5) exactly, a ``1 x 6`` Jacobian on *one* joint's
  state ``[p_i, v_i]``, the other end ``p_j`` taken as known. Each arm joint is a 6-state filter; after the
  measurement update the elbow is constrained to the forearm length from the wrist, then the shoulder to
  the upper-arm length from the (updated) elbow (the chain AKC uses; the paper names "two connected joints"
  and "a predefined arm length l", so the shoulder width is not constrained).
* :class:`ExtendedKalmanFilterCV` (``--protocol ours``): the six arm joints in one 36-state filter, every
  segment (shoulder width too) a pseudo-measurement on both of its ends, batched; with
  ``EKFConfig.length_tau_s`` (the default) plus one state per segment for the persistent part of its length
  error (41 states).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from akc_drake.core.kalman import (
    _SYMMETRISE_EVERY,
    _T_EPS,
    ConstantVelocityKF,
    EKFConfig,
    _check_dt,
    _check_z,
    _gate,
    _process_noise,
    status_from,
)
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, SEGMENT_NAMES, SEGMENTS, BodyDimensions

#: Constraint skipped when the two ends are closer than this (metres): the direction is undefined.
_MIN_CONSTRAINT_DIST = 1e-6


# Landmarks of the constrained (coupled) block of the EKF. With the order of ``skeleton.LANDMARKS``
# they are the first six (shoulders, elbows, wrists), which lets the EKF use slices, not copies.
_ARM = tuple(sorted({INDEX[n] for seg in SEGMENT_NAMES for n in SEGMENTS[seg]}))
if _ARM != tuple(range(len(_ARM))):  # pragma: no cover - guards a change of skeleton.LANDMARKS
    raise RuntimeError("the EKF expects the segment landmarks first in skeleton.LANDMARKS")
_NA = len(_ARM)



def _checked(dims, config) -> tuple[BodyDimensions, EKFConfig]:
    """``(dims, config)`` of an EKF, ``config`` defaulted; ValueError naming a wrong type."""
    if not isinstance(dims, BodyDimensions):
        raise ValueError(f"dims must be a BodyDimensions, got {type(dims).__name__}")
    config = EKFConfig() if config is None else config
    if not isinstance(config, EKFConfig):
        raise ValueError(f"config must be an EKFConfig, got {type(config).__name__}")
    return dims, config

class ExtendedKalmanFilterCV:
    """Constant-velocity EKF with bone-length pseudo-measurements (eq. 4-6).

    The arm landmarks (both shoulders, elbows and wrists) share one filter, state
    ``x = [p (18), v (18)]`` (landmark-major, x/y/z innermost) with a full covariance.
    After the measurement update each constrained segment adds the pseudo-measurement
    ``|p_i - p_j| = l`` with variance ``sigma_c^2``, all segments in one batch linearised at the
    updated state. A segment is skipped when an axis of either end is uninitialised or the ends
    coincide. The other landmarks run the decoupled :class:`ConstantVelocityKF`.

    With ``config.length_tau_s`` (the default) the state also holds ``b (5)``, one per segment: the persistent
    part of the difference between the landmarks' distance and the calibrated length, a first-order
    Gauss-Markov process (``b <- exp(-dt / tau) b``, stationary standard deviation ``length_sigma_m``,
    ``width_sigma_m`` for the shoulder width, starting at 0 with that variance), and the pseudo-measurement is
    ``|p_i - p_j| - b = l`` (``sigma_c`` its white part). An error that persists, such as a detected landmark
    moved on the body, is then one quantity the filter estimates, not fresh evidence every frame
    (:class:`~akc_drake.core.kalman.EKFConfig` says why).

    A held axis (see the module docstring) has its velocity and the velocity's covariance
    zeroed every step, so the motion model no longer moves it, but its position stays in the
    filter: the bone constraints keep correcting it (that is how the EKF recovers the depth of
    a joint whose depth measurement has been dropped for a long time).

    Args:
        dims: the operator's calibrated segment lengths (``l`` of eq. 4).
        config: noise model, track management and constraint settings.

    Same API as :class:`ConstantVelocityKF`.
    """

    def __init__(self, dims: BodyDimensions, config: EKFConfig | None = None):
        self.dims, self.config = dims, config = _checked(dims, config)
        self.num_landmarks = NUM_LANDMARKS
        self._n3 = n3 = 3 * _NA
        segs = config.segments
        nc = len(segs)
        # Length deviation states b (one per segment) after p and v, when the deviation is correlated in time.
        self._nb = nb = nc if config.length_tau_s is not None else 0
        self._n = n = 2 * n3 + nb
        self._limit = config.max_predict_s + _T_EPS
        self._r = np.tile(config.r, _NA)
        self._R = np.diag(self._r)
        self._q = np.tile(np.array(config.accel_psd, dtype=np.float64), _NA)
        self._side = ConstantVelocityKF(NUM_LANDMARKS - _NA, config.kf_config())

        # One buffer: M = [P | x] (n x (n + 1)), then age, initialised, rejects (n3 each) and a step
        # counter. Keeping x as the last column of P lets one matrix operation update both: the
        # prediction's row operation A [P | x] = [A P | A x], and each update
        # [P | x] -= P H^T S^-1 [(P H^T)^T | H x - z].
        # Positions are 0, not NaN, on uninitialised axes (their rows of P stay decoupled).
        self._buf = b = np.zeros(n * (n + 1) + 3 * n3 + 1)
        self._M = M = b[: n * (n + 1)].reshape(n, n + 1)
        self._P = M[:, :n]
        self._x = M[:, n]
        self._p = self._x[:n3]
        self._v = self._x[n3 : 2 * n3]
        self._b = self._x[2 * n3 :]
        o = n * (n + 1)
        self._age = b[o : o + n3]
        self._init = b[o + n3 : o + 2 * n3]
        self._rej = b[o + 2 * n3 : o + 3 * n3]
        self._count = b[o + 3 * n3 :]
        self._M_top, self._M_bottom = M[:n3], M[n3 : 2 * n3]
        self._P_left, self._P_right = M[:, :n3], M[:, n3 : 2 * n3]
        self._P_pp = M[:n3, :n3]
        self._M_b, self._P_colb = M[2 * n3 :], M[:, 2 * n3 : n]
        self._b_diag = np.arange(2 * n3, n)

        # Constraint k: segment between arm landmarks a_k and b_k.
        self._seg_names = segs
        ca = np.array([INDEX[SEGMENTS[s][0]] for s in segs], dtype=np.intp)
        cb = np.array([INDEX[SEGMENTS[s][1]] for s in segs], dtype=np.intp)
        self._ca, self._cb = ca, cb
        self._l = np.array([getattr(dims, s) for s in segs])
        # D: (3 nc, n3) with diff = D p = p_a - p_b per segment and axis.
        self._D = np.zeros((3 * nc, n3))
        rows = np.arange(3 * nc)
        self._D[rows, 3 * np.repeat(ca, 3) + np.tile(np.arange(3), nc)] = 1.0
        self._D[rows, 3 * np.repeat(cb, 3) + np.tile(np.arange(3), nc)] = -1.0
        # Axes (flat position indices) of both ends of each segment, for the skip test.
        self._seg_axes = np.stack([self._D[3 * k : 3 * k + 3].any(axis=0) for k in range(nc)])
        # H_c is written through flat indices: row k gets u_k at the columns of a_k, -u_k at b_k.
        self._Hc = np.zeros((nc, n))
        rk = np.repeat(np.arange(nc), 3)
        self._hc_flat = np.stack(
            (
                rk * n + 3 * np.repeat(ca, 3) + np.tile(np.arange(3), nc),
                rk * n + 3 * np.repeat(cb, 3) + np.tile(np.arange(3), nc),
            )
        )
        self._sign2 = np.array([[1.0], [-1.0]])
        # H_c's columns of b: -1 on row k at b_k (h(x) = |p_a - p_b| - b_k), zeroed for a skipped segment.
        self._hc_b = (np.arange(nb), 2 * n3 + np.arange(nb))
        self._Rc = np.eye(nc) * config.sigma_c**2
        self._phi_b = 1.0
        # Stationary variances of the length deviations (the shoulder width's is not a bone's).
        self._var_b = np.array([config.width_sigma_m if s == "SW" else config.length_sigma_m for s in segs[:nb]]) ** 2
        # Scratch.
        self._Q = np.zeros((n, n))
        self._T_rows = np.empty((n3, n + 1))
        self._T_cols = np.empty((n, n3))
        self._B = np.empty((n3, n + 1))
        self._Bc = np.empty((nc, n + 1))
        self._T_sym = np.empty((n, n))
        self._S = np.empty((n3, n3))
        self._S_diag = self._S.reshape(-1)[:: n3 + 1]
        self._vals = np.empty((2, 3 * nc))
        self._dt = None
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def state_size(self) -> int:
        """Length of :meth:`get_state_vector`."""
        return self._buf.size + self._side.state_size

    def reset(self) -> None:
        """Forget every track."""
        self._buf[...] = 0.0
        self._P[self._b_diag, self._b_diag] = self._var_b
        self._all_init = False
        self._oldest = 0.0
        self._side.reset()

    def get_state_vector(self) -> np.ndarray:
        """All filter state as a new 1-D float array."""
        return np.concatenate((self._buf, self._side.get_state_vector()))

    def set_state_vector(self, v) -> None:
        """Load the state written by :meth:`get_state_vector`."""
        a = np.asarray(v, dtype=np.float64).reshape(-1)
        if a.size != self.state_size:
            raise ValueError(f"state vector must have {self.state_size} entries, got {a.size}")
        nb = self._buf.size
        self._buf[...] = a[:nb]
        self._side.set_state_vector(a[nb:])
        self._all_init = bool(self._init.all())
        self._oldest = float(self._age.max())

    def _arm_view(self, flat: np.ndarray, nan_uninit: bool) -> np.ndarray:
        out = flat.reshape(_NA, 3).copy()
        if nan_uninit and not self._all_init:
            out[self._init.reshape(_NA, 3) == 0.0] = np.nan
        return out

    @property
    def initialised(self) -> np.ndarray:
        """``(12, 3)`` bool: the axis has been measured at least once."""
        return np.concatenate((self._init.reshape(_NA, 3) != 0.0, self._side.initialised))

    @property
    def position(self) -> np.ndarray:
        """Estimated positions ``(12, 3)``, NaN for axes never measured."""
        return np.concatenate((self._arm_view(self._p, True), self._side.position))

    @property
    def velocity(self) -> np.ndarray:
        """Estimated velocities ``(12, 3)`` (m/s), NaN for axes never measured."""
        return np.concatenate((self._arm_view(self._v, True), self._side.velocity))

    @property
    def position_variance(self) -> np.ndarray:
        """Marginal variance of each position axis ``(12, 3)``, NaN for axes never measured."""
        d = np.diagonal(self._P)[: self._n3]
        return np.concatenate((self._arm_view(d, True), self._side.position_variance))

    @property
    def axis_age(self) -> np.ndarray:
        """Seconds since each axis was last measured ``(12, 3)`` (0 for axes never measured)."""
        return np.concatenate((self._arm_view(self._age, False), self._side.axis_age))

    @property
    def arm_covariance(self) -> np.ndarray:
        """Copy of the 36 x 36 covariance of the arm block: positions then velocities, landmarks in
        the order of ``skeleton.ARM_JOINTS``, x/y/z innermost."""
        m = 2 * self._n3
        return self._P[:m, :m].copy()

    @property
    def length_deviation(self) -> dict[str, tuple[float, float]]:
        """Per constrained segment, ``(b, sd)``: the estimated deviation of the landmark distance from the
        calibrated length and its standard deviation, metres (``(0, 0)`` without ``EKFConfig.length_tau_s``)."""
        if not self._nb:
            return {s: (0.0, 0.0) for s in self._seg_names}
        sd = np.sqrt(np.diagonal(self._P)[self._b_diag])
        return {s: (float(b), float(d)) for s, b, d in zip(self._seg_names, self._b, sd, strict=True)}

    @property
    def status(self) -> np.ndarray:
        """``(12,)`` int: 0 UNINITIALISED, 1 TRACKING, 2 PREDICTING, 3 LOST."""
        init = self._init.reshape(_NA, 3) != 0.0
        arm = status_from(init, self._age.reshape(_NA, 3), self.config.max_predict_s)
        return np.concatenate((arm, self._side.status))

    def bone_lengths(self) -> dict[str, float]:
        """Current estimated length of every constrained segment (NaN if an end is uninitialised)."""
        pa = self._arm_view(self._p, True)
        d = np.linalg.norm(pa[self._ca] - pa[self._cb], axis=1)
        return dict(zip(self._seg_names, d.tolist(), strict=True))

    # ------------------------------------------------------------------ step
    def _set_dt(self, dt: float) -> None:
        n3 = self._n3
        Qpp, Qpv, Qvv = _process_noise(self._q, dt)
        i = np.arange(n3)
        Q = self._Q
        Q[i, i] = Qpp
        Q[i, i + n3] = Qpv
        Q[i + n3, i] = Qpv
        Q[i + n3, i + n3] = Qvv
        if self._nb:
            # Gauss-Markov length deviations: b <- phi b, plus variance var_b (1 - phi^2) (stationary var_b).
            self._phi_b = phi = math.exp(-dt / self.config.length_tau_s)
            Q[self._b_diag, self._b_diag] = self._var_b * (1.0 - phi * phi)
        self._dt = dt

    def _zero_rows_cols(self, rows: np.ndarray) -> None:
        """Zero the state entries ``rows`` with their rows and columns of P."""
        self._M[rows, :] = 0.0
        self._P[:, rows] = 0.0

    def step(self, z, dt: float) -> np.ndarray:
        """Advance by ``dt`` seconds and fuse measurement ``z``, then the bone-length constraints.

        Args:
            z: ``(12, 3)`` measured positions, NaN where missing.
            dt: time since the previous step, seconds (> 0).

        Returns:
            ``(12, 3)`` estimated positions (a new array), NaN only for axes never measured.

        Raises:
            ValueError: ``z`` has the wrong shape or ``dt`` is not positive.
        """
        z = _check_z(z, (NUM_LANDMARKS, 3))
        dt = _check_dt(dt)
        if dt != self._dt:
            self._set_dt(dt)
        side_est = self._side._step(z[_NA:].reshape(-1), dt)

        n3, n = self._n3, self._n
        M, P, p, age = self._M, self._P, self._p, self._age
        za = z[:_NA].reshape(-1)
        m = np.isfinite(za)
        limit = self._limit
        slow = not self._all_init or self._oldest + dt > limit
        if slow:
            # Held axes: stop extrapolating (zero the velocity, its rows of P and of x).
            held = np.flatnonzero((age > limit - dt) & ~m & (self._init != 0.0)) + n3
            if held.size:
                self._zero_rows_cols(held)
            reinit = m & ((self._init == 0.0) | (age > limit))
            use = m & ~reinit
        else:
            use = m

        # eq. (2), prediction x = A x, P = A P A^T + Q with A = [[I, dt I], [0, I]]:
        # A [P | x]: position rows += dt velocity rows; (A P) A^T: position cols += dt velocity cols
        self._M_top += np.multiply(self._M_bottom, dt, out=self._T_rows)
        self._P_left += np.multiply(self._P_right, dt, out=self._T_cols)
        if self._nb:  # b <- phi b: its rows (x included) and columns of [P | x]
            self._M_b *= self._phi_b
            self._P_colb *= self._phi_b
        P += self._Q
        if slow and held.size:
            self._zero_rows_cols(held)

        if self.config.gate_sigma is not None:
            if not slow:
                reinit = np.zeros_like(m)
                slow = True
            _gate(self.config, use, za - p, np.diagonal(P)[:n3] + self._r, self._rej, reinit, age + dt)

        # eq. (3), measurement update of the measured axes (H selects them; z-less -> x, y only):
        #   S = H P H^T + R,  K = P H^T S^-1,  x += K (z - H x),  P -= K H P
        # as one solve and one product: [P | x] -= P H^T S^-1 [(P H^T)^T | H x - z]. (Only the
        # columns P H^T are used, never the rows H P: with P symmetric they are equal, but using
        # the rows would let rounding asymmetry grow from step to step.)
        PHt = self._P_left
        B = self._B
        if all(use.tolist()):
            B[:, :n] = PHt.T
            np.subtract(p, za, out=B[:, n])
            S = np.add(self._P_pp, self._R, out=self._S)
        elif use.any():
            # Axes without a measurement are left out exactly: their rows of B are zero and their
            # rows and columns of S are those of the identity, so their rows of S^-1 B are zero.
            u = use.astype(np.float64)
            np.multiply(PHt.T, u[:, None], out=B[:, :n])
            B[:, n] = np.where(use, p - za, 0.0)
            S = np.multiply(self._P_pp, np.multiply.outer(u, u), out=self._S)
            self._S_diag += np.where(use, self._r, 1.0)
        else:
            S = None
        if S is not None:
            M -= PHt @ _spd_solve(S, B)

        if slow:
            if reinit.any():
                ri = np.flatnonzero(reinit)
                vi = ri + n3
                self._zero_rows_cols(ri)
                self._zero_rows_cols(vi)
                p[ri] = za[ri]
                P[ri, ri] = self._r[ri]
                P[vi, vi] = self.config.init_vel_var
                self._rej[ri] = 0.0
                self._init[ri] = 1.0
                use |= reinit
            if not self._all_init:
                self._all_init = bool(self._init.all())
        age += dt
        if not self._all_init:
            age[self._init == 0.0] = 0.0
        age[use] = 0.0
        self._oldest += dt
        if self._oldest + dt > limit:
            self._oldest = float(age.max())

        self._constrain()
        arm = p.reshape(_NA, 3)
        if not self._all_init:
            arm = np.where(self._init.reshape(_NA, 3) == 0.0, np.nan, arm)
        return np.concatenate((arm, side_est))

    def _constrain(self) -> None:
        """Bone-length pseudo-measurements (eq. 4-6) of all segments in one batch."""
        n = self._n
        diff = (self._D @ self._p).reshape(-1, 3)
        # eq. (4): h(x) = |p_i - p_j|
        h = np.sqrt(np.add.reduce(diff * diff, axis=1))
        if self._all_init and min(h.tolist()) > _MIN_CONSTRAINT_DIST:
            u = diff / h[:, None]
            # -(l + b - h(x))
            neg_resid = h - self._l
            active = None
        else:
            active = h > _MIN_CONSTRAINT_DIST
            if not self._all_init:
                active &= ~(self._seg_axes & (self._init == 0.0)).any(axis=1)
            if not active.any():
                return
            # Skipped segments get a zero row in H_c and a zero residual: their gain column is zero,
            # exactly as if they were left out.
            u = np.where(active[:, None], diff / np.where(active, h, 1.0)[:, None], 0.0)
            neg_resid = np.where(active, h - self._l, 0.0)
        # eq. (5): H_c row k = [u_k^T at p_a, -u_k^T at p_b, 0 elsewhere], u_k = (p_a - p_b) / h_k
        # (with the length deviation states, also -1 at b_k: h(x) = |p_a - p_b| - b_k)
        Hc = self._Hc
        Hc.reshape(-1)[self._hc_flat] = np.multiply(self._sign2, u.reshape(1, -1), out=self._vals)
        if self._nb:
            neg_resid = neg_resid - self._b
            if active is None:
                Hc[self._hc_b] = -1.0
            else:
                Hc[self._hc_b] = np.where(active, -1.0, 0.0)
                neg_resid[~active] = 0.0
        PHt = np.dot(self._P, Hc.T)
        # S_c = H_c P H_c^T + sigma_c^2 I
        S = Hc @ PHt
        S += self._Rc
        # eq. (6): x <- x + K_c (l - h(x)), P <- P - K_c H_c P, with K_c = P H_c^T S_c^-1:
        # [P | x] -= P H_c^T S_c^-1 [(P H_c^T)^T | h(x) - l]
        B = self._Bc
        B[:, :n] = PHt.T
        B[:, n] = neg_resid
        self._M -= PHt @ _spd_solve(S, B)
        # Make P exactly symmetric again every few steps: rounding makes it drift slowly (the
        # step counter is part of the state, so a replay symmetrises at the same steps).
        self._count += 1.0
        if self._count >= _SYMMETRISE_EVERY:
            self._count[...] = 0.0
            P = self._P
            np.add(P, P.T, out=self._T_sym)
            np.multiply(self._T_sym, 0.5, out=P)


def _spd_solve(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^-1 B`` for a symmetric positive definite ``S`` (LAPACK dposv; LU if S is not SPD)."""
    _, X, info = lapack.dposv(S, B)
    if info != 0:
        X = np.linalg.solve(S, B)
    return X


class PerJointEKF:
    """The paper's EKF (eq. 4-6): per-joint constant-velocity filters with a 1 x 6 bone-length Jacobian.

    Each arm joint (shoulders, elbows, wrists) is one 6-state filter ``[p, v]`` with a full 6 x 6 covariance
    (the constraint couples its axes); the other landmarks run the decoupled :class:`ConstantVelocityKF`.
    A step is the prediction (eq. 2), the measurement update of the measured axes (eq. 3; ``z`` missing ->
    the x, y partial update), then, per arm, the elbow constrained to the forearm length from the wrist and
    the shoulder to the upper-arm length from the elbow, each as the scalar update of eq. (6) with the
    Jacobian of eq. (5) on that joint alone and variance ``sigma_c^2``. Holding after ``max_predict_s`` is as
    in the KF (``math.inf``: never, the paper's).

    Args:
        dims: calibrated arm lengths (``l``).
        config: noise model (``sigma_c`` the constraint's standard deviation; ``segments`` is not used: the
            four arm segments are constrained).
    """

    # (constrained joint, reference joint, segment)
    _CHAIN = (
        (INDEX["left_elbow"], INDEX["left_wrist"], "LLA"),
        (INDEX["left_shoulder"], INDEX["left_elbow"], "LUA"),
        (INDEX["right_elbow"], INDEX["right_wrist"], "RLA"),
        (INDEX["right_shoulder"], INDEX["right_elbow"], "RUA"),
    )

    def __init__(self, dims: BodyDimensions, config: EKFConfig | None = None):
        self.dims, self.config = dims, config = _checked(dims, config)
        self.num_landmarks = NUM_LANDMARKS
        self._lengths = {s: getattr(dims, s) for s in ("LUA", "LLA", "RUA", "RLA")}
        self._r = np.asarray(config.r, dtype=float)
        self._q = np.asarray(config.accel_psd, dtype=float)
        self._rc = config.sigma_c**2
        self._limit = config.max_predict_s + _T_EPS
        self._side = ConstantVelocityKF(NUM_LANDMARKS - _NA, config.kf_config())
        self._dt = None
        self.reset()

    def reset(self) -> None:
        self._x = np.zeros((_NA, 6))
        self._P = np.zeros((_NA, 6, 6))
        self._init = np.zeros((_NA, 3), dtype=bool)
        self._age = np.zeros((_NA, 3))
        self._rej = np.zeros((_NA, 3))  # (the gate's consecutive rejections per axis)
        self._side.reset()

    def _set_dt(self, dt: float) -> None:
        A = np.eye(6)
        A[:3, 3:] = dt * np.eye(3)
        self._A = A
        qpp, qpv, qvv = _process_noise(self._q, dt)
        Q = np.zeros((6, 6))
        Q[:3, :3] = np.diag(qpp)
        Q[:3, 3:] = Q[3:, :3] = np.diag(qpv)
        Q[3:, 3:] = np.diag(qvv)
        self._Q = Q
        self._dt = dt

    @property
    def position(self) -> np.ndarray:
        """``(12, 3)`` the current position estimates (NaN where never measured)."""
        arm = np.where(self._init, self._x[:, :3], np.nan)
        return np.concatenate((arm, self._side.position))

    @property
    def position_variance(self) -> np.ndarray:
        """``(12, 3)`` the position variances (NaN where never measured)."""
        arm = np.where(self._init, np.diagonal(self._P, axis1=1, axis2=2)[:, :3], np.nan)
        return np.concatenate((arm, self._side.position_variance))

    @property
    def axis_age(self) -> np.ndarray:
        """Seconds since each axis was last measured ``(12, 3)`` (0 for axes never measured)."""
        return np.concatenate((np.where(self._init, self._age, 0.0), self._side.axis_age))

    @property
    def status(self) -> np.ndarray:
        """``(12,)`` per-landmark status (see :func:`~akc_drake.core.kalman.status_from`)."""
        arm = status_from(self._init, self._age, self.config.max_predict_s)
        return np.concatenate((arm, self._side.status))

    def step(self, z, dt: float) -> np.ndarray:
        """Advance by ``dt``, fuse ``z`` ``(12, 3)`` (NaN where missing), then the bone-length constraints.

        Returns:
            ``(12, 3)`` estimated positions, NaN only for axes never measured.

        Raises:
            ValueError: ``z`` has the wrong shape or ``dt`` is not positive.
        """
        z = _check_z(z, (NUM_LANDMARKS, 3))
        dt = _check_dt(dt)
        if dt != self._dt:
            self._set_dt(dt)
        side = self._side._step(z[_NA:].reshape(-1), dt)
        A, Q, r = self._A, self._Q, self._r
        X, P = self._x, self._P
        za = z[:_NA]
        meas = np.isfinite(za)
        self._age += dt
        held = (self._age > self._limit) & ~meas & self._init
        if held.any():  # stop extrapolating a lost axis (not with the paper's inf)
            X[:, 3:][held] = 0.0
        # eq. (2), prediction of every joint at once
        X[:] = X @ A.T
        P[:] = A @ P @ A.T + Q
        if held.any():
            for j, a in zip(*np.nonzero(held), strict=True):
                P[j, 3 + a, :] = 0.0
                P[j, :, 3 + a] = 0.0
        for j in range(_NA):
            m = meas[j]
            if not m.any():
                continue
            new = m & (~self._init[j] | (self._age[j] > self._limit))
            use = m & ~new
            if self.config.gate_sigma is not None and use.any():
                y_all = np.where(use, za[j] - X[j, :3], 0.0)
                S_all = np.diagonal(P[j])[:3] + r
                _gate(self.config, use, y_all, S_all, self._rej[j], new, self._age[j])  # (forced: re-initialised)
            for a in np.flatnonzero(new):  # (re)initialise: p = z, v = 0, decoupled covariance
                P[j, a, :] = P[j, :, a] = 0.0
                P[j, 3 + a, :] = P[j, :, 3 + a] = 0.0
                X[j, a], X[j, 3 + a] = za[j, a], 0.0
                P[j, a, a], P[j, 3 + a, 3 + a] = r[a], self.config.init_vel_var
                self._init[j, a] = True
                self._rej[j, a] = 0.0
            idx = np.flatnonzero(use)
            if idx.size:
                # eq. (3): S = H P H^T + R, K = P H^T S^-1, x += K (z - H x), P -= K H P
                PHt = P[j][:, idx]
                S = PHt[idx, :] + np.diag(r[idx])
                K = np.linalg.solve(S, PHt.T).T
                X[j] += K @ (za[j, idx] - X[j, idx])
                P[j] -= K @ PHt.T
            self._age[j, use | new] = 0.0  # (an axis the gate rejected keeps ageing)
        # eq. (4)-(6), the chain elbow <- wrist, shoulder <- elbow, each on one joint's 6 states
        for i, k, seg in self._CHAIN:
            if not (self._init[i].all() and self._init[k].all()):
                continue
            d = X[i, :3] - X[k, :3]
            h = math.sqrt(float(d @ d))
            if h < _MIN_CONSTRAINT_DIST:
                continue
            H = np.zeros(6)
            H[:3] = d / h  # eq. (5)
            PHt = P[i] @ H
            S = float(H @ PHt) + self._rc
            K = PHt / S
            X[i] += K * (self._lengths[seg] - h)  # eq. (6)
            P[i] -= np.outer(K, PHt)
        P[:] = 0.5 * (P + np.transpose(P, (0, 2, 1)))
        arm = np.where(self._init, X[:, :3], np.nan)
        return np.concatenate((arm, side))
