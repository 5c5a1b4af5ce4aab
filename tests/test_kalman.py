"""Tests of akc_drake.core.kalman: the vectorised CV Kalman filter and the bone-length EKF.

The references below are deliberately plain textbook filters with full matrices (FilterPy style:
x, P, F, H, Q, R, K, S, y), one 6-state filter per landmark for the KF and one dense 36-state EKF
for the arm landmarks, so that the vectorised implementations are checked against an
independent formulation.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from akc_drake.core.ekf import PerJointEKF
from akc_drake.core.kalman import (
    LOST,
    PREDICTING,
    TRACKING,
    UNINITIALISED,
    ConstantVelocityKF,
    EKFConfig,
    ExtendedKalmanFilterCV,
    KFConfig,
)
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, SEGMENTS, BodyDimensions, segment_lengths

DIMS = BodyDimensions.paper_participant()


# ---------------------------------------------------------------------------------------------- references
class TextbookKF:
    """One 6-state constant-velocity KF [x y z vx vy vz] with full matrices (eq. 1-3).

    An axis is initialised by its first measurement (x = z, v = 0, P = diag(r, init_vel_var) on
    that axis); afterwards the measured, initialised axes form H.
    """

    def __init__(self, cfg: KFConfig):
        self.cfg = cfg
        self.x = np.zeros(6)
        self.P = np.zeros((6, 6))
        self.init = np.zeros(3, dtype=bool)
        self.R_full = np.diag(cfg.r)

    def F(self, dt):
        F = np.eye(6)
        F[0:3, 3:6] = dt * np.eye(3)
        return F

    def Q(self, dt):
        q = np.diag(cfg_q(self.cfg))
        Q = np.zeros((6, 6))
        Q[0:3, 0:3] = q * dt**3 / 3.0
        Q[0:3, 3:6] = q * dt**2 / 2.0
        Q[3:6, 0:3] = q * dt**2 / 2.0
        Q[3:6, 3:6] = q * dt
        return Q

    def step(self, z, dt):
        F = self.F(dt)
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + self.Q(dt)
        measured = np.isfinite(z)
        upd = np.flatnonzero(measured & self.init)
        if upd.size:
            H = np.zeros((upd.size, 6))
            H[np.arange(upd.size), upd] = 1.0
            R = self.R_full[np.ix_(upd, upd)]
            y = z[upd] - H @ self.x
            S = H @ self.P @ H.T + R
            K = self.P @ H.T @ np.linalg.inv(S)
            self.x = self.x + K @ y
            self.P = (np.eye(6) - K @ H) @ self.P
        for a in np.flatnonzero(measured & ~self.init):
            for i in (a, a + 3):
                self.P[i, :] = 0.0
                self.P[:, i] = 0.0
            self.x[a], self.x[a + 3] = z[a], 0.0
            self.P[a, a] = self.cfg.r[a]
            self.P[a + 3, a + 3] = self.cfg.init_vel_var
            self.init[a] = True
        return np.where(self.init, self.x[:3], np.nan)


def cfg_q(cfg):
    return np.array(cfg.accel_psd, dtype=float)


class TextbookEKF:
    """Dense EKF for the six arm landmarks: state [p (18), v (18)] (+ [b (5)] with length_tau_s), P 36 x 36 (eq. 1-6).

    Same initialisation rule as :class:`TextbookKF`; after the measurement update the active
    segments (every axis of both ends initialised) form one batch of pseudo-measurements
    h(x) = |p_i - p_j| with H_c from eq. (5), R_c = sigma_c^2 I. With ``cfg.length_tau_s`` each segment
    also has a Gauss-Markov length deviation b_k (b <- phi b, phi = exp(-dt / tau), stationary variance
    length_sigma_m^2, width_sigma_m^2 for SW) and the pseudo-measurement is |p_i - p_j| - b_k = l.
    """

    NA = 6

    def __init__(self, dims: BodyDimensions, cfg: EKFConfig):
        self.cfg = cfg
        n3 = 3 * self.NA
        self.n3 = n3
        self.nb = nb = len(cfg.segments) if cfg.length_tau_s is not None else 0
        self.var_b = np.array([cfg.width_sigma_m if s == "SW" else cfg.length_sigma_m for s in cfg.segments][:nb]) ** 2
        self.x = np.zeros(2 * n3 + nb)
        self.P = np.zeros((2 * n3 + nb, 2 * n3 + nb))
        self.P[2 * n3 :, 2 * n3 :] = np.diag(self.var_b)
        self.init = np.zeros(n3, dtype=bool)
        self.r = np.tile(cfg.r, self.NA)
        self.q = np.tile(cfg_q(cfg), self.NA)
        self.pairs = [(INDEX[SEGMENTS[s][0]], INDEX[SEGMENTS[s][1]], getattr(dims, s)) for s in cfg.segments]
        self.side = [TextbookKF(cfg.kf_config()) for _ in range(NUM_LANDMARKS - self.NA)]

    def step(self, z, dt):
        n3 = self.n3
        side = np.array([f.step(z[self.NA + j], dt) for j, f in enumerate(self.side)])
        za = z[: self.NA].reshape(-1)
        N = 2 * n3 + self.nb
        F = np.eye(N)
        F[:n3, n3 : 2 * n3] = dt * np.eye(n3)
        Q = np.zeros((N, N))
        Q[:n3, :n3] = np.diag(self.q * dt**3 / 3)
        Q[:n3, n3 : 2 * n3] = np.diag(self.q * dt**2 / 2)
        Q[n3 : 2 * n3, :n3] = np.diag(self.q * dt**2 / 2)
        Q[n3 : 2 * n3, n3 : 2 * n3] = np.diag(self.q * dt)
        if self.nb:
            phi = np.exp(-dt / self.cfg.length_tau_s)
            F[2 * n3 :, 2 * n3 :] = phi * np.eye(self.nb)
            Q[2 * n3 :, 2 * n3 :] = np.diag(self.var_b * (1 - phi**2))
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q
        measured = np.isfinite(za)
        upd = np.flatnonzero(measured & self.init)
        if upd.size:
            H = np.zeros((upd.size, N))
            H[np.arange(upd.size), upd] = 1.0
            y = za[upd] - H @ self.x
            S = H @ self.P @ H.T + np.diag(self.r[upd])
            K = self.P @ H.T @ np.linalg.inv(S)
            self.x = self.x + K @ y
            self.P = (np.eye(N) - K @ H) @ self.P
        for a in np.flatnonzero(measured & ~self.init):
            for i in (a, a + n3):
                self.P[i, :] = 0.0
                self.P[:, i] = 0.0
            self.x[a], self.x[a + n3] = za[a], 0.0
            self.P[a, a] = self.r[a]
            self.P[a + n3, a + n3] = self.cfg.init_vel_var
            self.init[a] = True
        # bone-length constraints, only the active ones
        rows, res = [], []
        for k, (i, j, length) in enumerate(self.pairs):
            ia, ib = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
            if not (self.init[ia].all() and self.init[ib].all()):
                continue
            d = self.x[ia] - self.x[ib]
            h = np.linalg.norm(d)
            if h < 1e-6:
                continue
            Hc = np.zeros(N)
            Hc[ia] = d / h
            Hc[ib] = -d / h
            b = 0.0
            if self.nb:
                Hc[2 * n3 + k] = -1.0
                b = self.x[2 * n3 + k]
            rows.append(Hc)
            res.append(length - (h - b))
        if rows:
            Hc = np.array(rows)
            S = Hc @ self.P @ Hc.T + self.cfg.sigma_c**2 * np.eye(len(rows))
            K = self.P @ Hc.T @ np.linalg.inv(S)
            self.x = self.x + K @ np.array(res)
            self.P = (np.eye(N) - K @ Hc) @ self.P
        arm = np.where(self.init, self.x[:n3], np.nan).reshape(self.NA, 3)
        return np.concatenate((arm, side))


# ---------------------------------------------------------------------------------------------- data
def random_sequence(rng, T, *, p_missing=0.15, p_zless=0.2, late=(3, 7, 10)):
    """Noisy random-walk landmarks (T, 12, 3) with NaN dropouts, z-only dropouts, late starters."""
    base = rng.uniform(-0.4, 0.4, size=(NUM_LANDMARKS, 3)) + [0.0, 0.0, 2.0]
    vel = rng.normal(scale=0.2, size=(NUM_LANDMARKS, 3))
    walk = np.cumsum(rng.normal(scale=0.01, size=(T, NUM_LANDMARKS, 3)), axis=0)
    truth = base + vel * np.arange(T)[:, None, None] * 0.1 + walk
    z = truth + rng.normal(size=truth.shape) * [0.01, 0.01, 0.05]
    z[rng.random((T, NUM_LANDMARKS)) < p_missing] = np.nan
    z[rng.random((T, NUM_LANDMARKS)) < p_zless, 2] = np.nan
    for j in late:  # never seen at first; one of them first appears without depth
        z[: 5 + j, j] = np.nan
    z[5 + late[0], late[0], 2] = np.nan
    return z


def arm_track(T, dims, dt=0.1):
    """A smooth two-arm motion (T, 12, 3) with exactly the segment lengths of ``dims``."""
    t = np.arange(T) * dt
    out = np.zeros((T, NUM_LANDMARKS, 3))
    for k, tt in enumerate(t):
        ls, rs = np.array([-dims.SW / 2, 0.0, 2.0]), np.array([dims.SW / 2, 0.0, 2.0])
        a = 0.8 * np.sin(2 * np.pi * tt / 6)
        b = 0.6 + 0.5 * np.sin(2 * np.pi * tt / 6 + 1)
        joints = []
        for sign, s, up, lo in ((-1, ls, dims.LUA, dims.LLA), (1, rs, dims.RUA, dims.RLA)):
            d_up = np.array([sign * np.cos(a) * 0.3, np.sin(a), -0.3])
            d_lo = np.array([sign * np.sin(b) * 0.2, np.cos(b), -np.sin(b)])
            e = s + up * d_up / np.linalg.norm(d_up)
            w = e + lo * d_lo / np.linalg.norm(d_lo)
            joints.append((s, e, w))
        (ls, le, lw), (rs, re, rw) = joints
        out[k, :6] = [ls, rs, le, re, lw, rw]
        out[k, 6:] = [
            lw + [0, 0.08, 0],
            rw + [0, 0.08, 0],
            lw + [0, 0.09, -0.02],
            rw + [0, 0.09, -0.02],
            ls + [0.05, 0.5, 0],
            rs + [-0.05, 0.5, 0],
        ]
    return out


def noisy(truth, cfg, rng):
    return truth + rng.normal(size=truth.shape) * [cfg.sigma_x, cfg.sigma_y, cfg.sigma_z]


# ---------------------------------------------------------------------------------------------- KF
def test_vectorised_kf_equals_textbook_6_state_filter():
    rng = np.random.default_rng(7)
    cfg = KFConfig(accel_psd=(0.3, 0.5, 0.8), max_predict_s=100.0)
    z = random_sequence(rng, 120)
    dts = rng.uniform(0.05, 0.15, size=len(z))
    kf = ConstantVelocityKF(config=cfg)
    refs = [TextbookKF(cfg) for _ in range(NUM_LANDMARKS)]
    worst = 0.0
    for k in range(len(z)):
        est = kf.step(z[k], dts[k])
        ref = np.array([f.step(z[k, j], dts[k]) for j, f in enumerate(refs)])
        np.testing.assert_array_equal(np.isnan(est), np.isnan(ref))
        worst = max(worst, np.nanmax(np.abs(est - ref)))
        v_ref = np.array([np.where(f.init, f.x[3:], np.nan) for f in refs])
        var_ref = np.array([np.where(f.init, np.diag(f.P)[:3], np.nan) for f in refs])
        np.testing.assert_allclose(kf.velocity, v_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(kf.position_variance, var_ref, rtol=0, atol=1e-12)
    assert worst < 1e-12
    # the late starters were really uninitialised for a while and are now tracked
    assert not np.isnan(est).any()


def test_kf_converges_on_noisy_constant_velocity_track():
    rng = np.random.default_rng(1)
    dt, T = 0.1, 200
    cfg = KFConfig(accel_psd=(1e-4, 1e-4, 1e-4))
    p0 = rng.uniform(-0.5, 0.5, (NUM_LANDMARKS, 3)) + [0, 0, 2]
    v0 = rng.uniform(-0.2, 0.2, (NUM_LANDMARKS, 3))
    truth = p0 + v0 * (np.arange(T) * dt)[:, None, None]
    z = noisy(truth, cfg, rng)
    kf = ConstantVelocityKF(config=cfg)
    est = np.array([kf.step(zk, dt) for zk in z])
    rmse = np.sqrt(((est - truth)[50:] ** 2).mean(axis=(0, 1)))
    sigma = np.array([cfg.sigma_x, cfg.sigma_y, cfg.sigma_z])
    assert (rmse < 0.5 * sigma).all(), (rmse, sigma)
    np.testing.assert_allclose(kf.velocity, v0, atol=0.02)
    # a 0.5 s gap: pure prediction along the learnt velocity
    for _ in range(5):
        gap = kf.step(np.full((NUM_LANDMARKS, 3), np.nan), dt)
        assert (kf.status == PREDICTING).all()
    truth_gap = p0 + v0 * (T + 4) * dt
    # after 0.5 s without data the prediction is still better than a single measurement
    rmse_gap = np.sqrt(((gap - truth_gap) ** 2).mean(axis=0))
    assert (rmse_gap < 0.8 * sigma).all(), (rmse_gap, sigma)
    # ... while a filter that had not learnt the velocity would be off by |v| * 0.5 s
    assert np.sqrt(((gap - (p0 + v0 * (T - 1) * dt)) ** 2).mean()) > 0.04


def test_partial_update_leaves_z_to_the_prediction_and_updates_x_y():
    rng = np.random.default_rng(3)
    kf = ConstantVelocityKF()
    base = rng.uniform(-0.3, 0.3, (NUM_LANDMARKS, 3)) + [0, 0, 2]
    for k in range(10):
        kf.step(base + 0.05 * k + rng.normal(scale=0.01, size=base.shape), 0.1)
    p, v = kf.position, kf.velocity
    var_before = kf.position_variance
    z = base + 0.5 + 0.3  # far from the prediction in x and y
    z[:, 2] = np.nan
    est = kf.step(z, 0.1)
    predicted = p + 0.1 * v
    np.testing.assert_allclose(est[:, 2], predicted[:, 2], rtol=0, atol=1e-15)
    # x, y moved from the prediction toward the measurement, most of the way (sigma_xy is small)
    frac = (est[:, :2] - predicted[:, :2]) / (z[:, :2] - predicted[:, :2])
    assert ((frac > 0.5) & (frac < 1.0)).all()
    # z variance grew (prediction only), x/y variance shrank below sigma_xy^2
    var = kf.position_variance
    assert (var[:, 2] > var_before[:, 2]).all()
    assert (var[:, :2] < KFConfig().sigma_x ** 2).all()
    assert (kf.status == TRACKING).all()


def test_lost_after_max_predict_s_then_position_held_and_reinitialised():
    cfg = KFConfig(max_predict_s=1.0)
    kf = ConstantVelocityKF(config=cfg)
    dt = 0.1
    for k in range(30):
        z = np.zeros((NUM_LANDMARKS, 3))
        z[:, 0] = 0.2 * k * dt  # 0.2 m/s along x
        kf.step(z, dt)
    missing = np.full((NUM_LANDMARKS, 3), np.nan)
    missing[1:] = 0.0  # only landmark 0 disappears
    last = kf.position[0].copy()
    xs = []
    for _ in range(10):  # 1.0 s: still extrapolating
        xs.append(kf.step(missing, dt)[0, 0])
        assert kf.status[0] == PREDICTING
    assert xs[-1] == pytest.approx(last[0] + 0.2 * 1.0, abs=0.01)
    assert np.all(np.diff(xs) > 0.015)
    held = kf.step(missing, dt)[0]  # 1.1 s: beyond max_predict_s
    assert kf.status[0] == LOST
    assert (kf.status[1:] == TRACKING).all()
    assert held[0] == xs[-1]
    np.testing.assert_array_equal(kf.velocity[0], 0.0)
    for _ in range(5):
        np.testing.assert_array_equal(kf.step(missing, dt)[0], held)
        assert kf.status[0] == LOST
    # the next measurement re-initialises the track: estimate = measurement exactly
    back = missing.copy()
    back[0] = [0.9, -0.1, 2.5]
    np.testing.assert_array_equal(kf.step(back, dt)[0], back[0])
    assert kf.status[0] == TRACKING
    np.testing.assert_array_equal(kf.velocity[0], 0.0)
    np.testing.assert_allclose(kf.position_variance[0], cfg.r)


def test_depth_only_loss_holds_z_but_landmark_stays_tracking():
    kf = ConstantVelocityKF(config=KFConfig(max_predict_s=0.5))
    for k in range(10):
        kf.step(np.full((NUM_LANDMARKS, 3), [0.0, 0.0, 2.0 + 0.1 * k]), 0.1)
    z = np.full((NUM_LANDMARKS, 3), [0.1, 0.1, np.nan])
    zs = [kf.step(z, 0.1)[0, 2] for _ in range(12)]
    assert (kf.status == TRACKING).all()
    assert zs[4] > zs[0]  # extrapolated for 0.5 s
    assert zs[5] == zs[4] and zs[11] == zs[4]  # then held
    assert kf.axis_age[0, 2] == pytest.approx(1.2)
    assert kf.axis_age[0, 0] == 0.0


def test_never_measured_landmark_stays_nan_and_uninitialised():
    kf = ConstantVelocityKF()
    z = np.ones((NUM_LANDMARKS, 3))
    z[4] = np.nan
    z[5, 2] = np.nan
    for _ in range(3):
        est = kf.step(z, 0.1)
    assert np.isnan(est[4]).all() and np.isnan(kf.velocity[4]).all()
    assert np.isnan(est[5, 2]) and np.isfinite(est[5, :2]).all()
    assert kf.status[4] == UNINITIALISED and kf.status[5] == TRACKING
    np.testing.assert_array_equal(kf.initialised[5], [True, True, False])


def test_innovation_gate_rejects_outlier_but_cannot_lock_out():
    cfg = KFConfig(gate_sigma=4.0, gate_max_rejects=3, accel_psd=(0.01, 0.01, 0.01))
    kf = ConstantVelocityKF(config=cfg)
    z = np.full((NUM_LANDMARKS, 3), [0.0, 0.0, 2.0])
    rng = np.random.default_rng(0)
    for _ in range(20):
        kf.step(z + rng.normal(scale=0.005, size=z.shape), 0.1)
    jump = z.copy()
    jump[0, 0] = 1.0  # a 1 m jump of one axis
    for k in range(2):  # rejected twice: the estimate stays on the old track
        est = kf.step(jump, 0.1)
        assert abs(est[0, 0]) < 0.02
        assert kf.axis_age[0, 0] == pytest.approx(0.1 * (k + 1))
        assert kf.axis_age[0, 1] == 0.0
    est = kf.step(jump, 0.1)  # third consecutive rejection -> accepted, track re-initialised
    assert est[0, 0] == 1.0
    assert kf.status[0] == TRACKING
    # without the gate the jump is fused immediately
    plain = ConstantVelocityKF(config=KFConfig(accel_psd=(0.01, 0.01, 0.01)))
    for _ in range(20):
        plain.step(z, 0.1)
    assert plain.step(jump, 0.1)[0, 0] > 0.1


@pytest.mark.parametrize("make", [lambda cfg: ConstantVelocityKF(config=cfg),
                                  lambda cfg: ExtendedKalmanFilterCV(DIMS, cfg),
                                  lambda cfg: PerJointEKF(DIMS, cfg)], ids=["KF", "EKF", "per-joint EKF"])
def test_gate_speed_floor_passes_what_a_body_can_move_and_grows_with_the_gap(make):
    """``gate_speed_m_s``: an innovation within the speed times the time since the axis was last measured is
    never rejected, however many standard deviations it is; beyond it the gate acts as before."""
    rng = np.random.default_rng(0)
    base = np.array([[0.3 * np.cos(j), 0.1 * j - 0.5, 2.0 + 0.05 * j] for j in range(NUM_LANDMARKS)])
    w = INDEX["left_wrist"]

    def run(jump_m, floor, missed=0):
        kw = dict(gate_sigma=5.0, gate_whole_landmark=True, accel_psd=(0.01, 0.01, 0.01))
        cfg = EKFConfig(gate_speed_m_s=floor, **kw)  # (a KFConfig too: the KF reads its fields)
        f = make(cfg)
        for _ in range(20):
            f.step(base + rng.normal(scale=0.002, size=base.shape), 0.1)
        gap = base.copy()
        gap[w] = np.nan
        for _ in range(missed):
            f.step(gap, 0.1)
        z = base.copy()
        z[w, 0] += jump_m  # tens of standard deviations: the 5-sigma gate alone rejects it
        return f.step(z, 0.1)[w, 0] - base[w, 0]

    # (Taken: the filter moves towards the reading; the EKF's bone constraints hold back a wrist that left its
    # forearm's length, the KF goes 90 % of the way.)
    assert abs(run(0.4, None)) < 0.02  # no floor: rejected, the estimate stays on the track
    assert run(0.4, 6.0) > 0.15  # within 6 m/s x 0.1 s: taken
    assert abs(run(0.8, 6.0)) < 0.02  # beyond it: rejected
    assert run(0.8, 6.0, missed=1) > 0.3  # two frames since the last reading: 1.2 m allowed


def test_state_vector_round_trip_replays_identically():
    rng = np.random.default_rng(5)
    z = random_sequence(rng, 60)
    for make in (ConstantVelocityKF, lambda: ExtendedKalmanFilterCV(DIMS)):
        a = make()
        for k in range(30):
            a.step(z[k], 0.1)
        saved = a.get_state_vector()
        assert saved.ndim == 1 and saved.size == a.state_size
        rest_a = np.array([a.step(z[k], 0.1) for k in range(30, 60)])
        b = make()
        b.set_state_vector(saved)
        rest_b = np.array([b.step(z[k], 0.1) for k in range(30, 60)])
        np.testing.assert_array_equal(rest_a, rest_b)
        np.testing.assert_array_equal(a.status, b.status)
        a.reset()
        assert (a.status == UNINITIALISED).all() and np.isnan(a.position).all()


def test_bad_input_raises_value_error_naming_the_field():
    kf = ConstantVelocityKF()
    with pytest.raises(ValueError, match=r"shape \(12, 3\)"):
        kf.step(np.zeros((11, 3)), 0.1)
    for dt in (0.0, -0.1, float("nan"), float("inf"), "x"):
        with pytest.raises(ValueError, match="dt"):
            kf.step(np.zeros((12, 3)), dt)
    with pytest.raises(ValueError, match="state vector must have"):
        kf.set_state_vector(np.zeros(3))
    with pytest.raises(ValueError, match="sigma_z"):
        KFConfig(sigma_z=-1.0)
    with pytest.raises(ValueError, match="accel_psd"):
        KFConfig(accel_psd=(1.0, 2.0))
    with pytest.raises(ValueError, match="gate_max_rejects"):
        KFConfig(gate_max_rejects=0)
    with pytest.raises(ValueError, match="gate_speed_m_s"):
        KFConfig(gate_speed_m_s=-1.0)
    with pytest.raises(ValueError, match="max_predict_s"):
        KFConfig(max_predict_s=0.0)
    with pytest.raises(ValueError, match="sigma_c"):
        EKFConfig(sigma_c=0.0)
    with pytest.raises(ValueError, match="segments"):
        EKFConfig(segments=("LUA", "XYZ"))
    with pytest.raises(ValueError, match="length_tau_s"):
        EKFConfig(length_tau_s=0.0)
    with pytest.raises(ValueError, match="width_sigma_m"):
        EKFConfig(width_sigma_m=-0.01)
    with pytest.raises(ValueError, match="length_sigma_m"):
        EKFConfig(length_sigma_m=float("nan"))
    with pytest.raises(ValueError, match="BodyDimensions"):
        ExtendedKalmanFilterCV(None)
    with pytest.raises(ValueError, match="num_landmarks"):
        ConstantVelocityKF(0)


def test_default_noise_is_much_larger_in_depth():
    cfg = KFConfig()
    assert cfg.sigma_z >= 4 * max(cfg.sigma_x, cfg.sigma_y)
    assert EKFConfig().kf_config() == cfg


# ---------------------------------------------------------------------------------------------- EKF
@pytest.mark.parametrize("tau", [None, 2.0])
def test_ekf_equals_textbook_dense_ekf(tau):
    rng = np.random.default_rng(11)
    cfg = EKFConfig(accel_psd=(0.3, 0.4, 0.6), max_predict_s=100.0, sigma_c=0.02, length_tau_s=tau)
    truth = arm_track(150, DIMS)
    z = noisy(truth, cfg, rng)
    z[rng.random(z.shape[:2]) < 0.1] = np.nan
    z[rng.random(z.shape[:2]) < 0.2, 2] = np.nan
    z[:6, 2] = np.nan  # left elbow appears late
    z[6, 2, 2] = np.nan  # ... first without depth
    dts = rng.uniform(0.08, 0.12, size=len(z))
    ekf = ExtendedKalmanFilterCV(DIMS, cfg)
    ref = TextbookEKF(DIMS, cfg)
    worst = 0.0
    for k in range(len(z)):
        est = ekf.step(z[k], dts[k])
        r = ref.step(z[k], dts[k])
        np.testing.assert_array_equal(np.isnan(est), np.isnan(r))
        worst = max(worst, np.nanmax(np.abs(est - r)))
    assert worst < 1e-9
    np.testing.assert_allclose(ekf.arm_covariance, ref.P[:36, :36], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ekf.velocity[:6], ref.x[18:36].reshape(6, 3), rtol=0, atol=1e-9)
    dev = ekf.length_deviation
    if tau is None:
        assert all(v == (0.0, 0.0) for v in dev.values())
    else:
        np.testing.assert_allclose([dev[s][0] for s in cfg.segments], ref.x[36:], rtol=0, atol=1e-9)
        np.testing.assert_allclose([dev[s][1] ** 2 for s in cfg.segments], np.diag(ref.P)[36:], rtol=0, atol=1e-12)
    assert not np.isnan(est).any()


def test_ekf_pulls_bone_lengths_toward_calibration():
    rng = np.random.default_rng(2)
    truth = arm_track(400, DIMS)
    cfg = EKFConfig()
    z = noisy(truth, cfg, rng)
    z[rng.random(z.shape[:2]) < 0.2, 2] = np.nan
    kf, ekf = ConstantVelocityKF(), ExtendedKalmanFilterCV(DIMS, cfg)
    est_kf = np.array([kf.step(zk, 0.1) for zk in z])[20:]
    est_ekf = np.array([ekf.step(zk, 0.1) for zk in z])[20:]
    for name in ("LUA", "LLA", "RUA", "RLA", "SW"):
        length = getattr(DIMS, name)
        e_kf = np.sqrt(np.mean((segment_lengths(est_kf)[name] - length) ** 2))
        e_ekf = np.sqrt(np.mean((segment_lengths(est_ekf)[name] - length) ** 2))
        # the shoulder width is held more loosely than a bone (EKFConfig.width_sigma_m: not a bone)
        assert e_ekf < (0.7 if name == "SW" else 0.4) * e_kf, (name, e_kf, e_ekf)
        assert e_ekf < 0.01
    # and the joints themselves are estimated better in depth
    rmse = lambda e: np.sqrt(((e - truth[20:])[:, :6] ** 2).mean(axis=(0, 1)))  # noqa: E731
    assert rmse(est_ekf)[2] < rmse(est_kf)[2]
    # the other landmarks are the plain KF's
    np.testing.assert_allclose(est_ekf[:, 6:], est_kf[:, 6:], rtol=0, atol=1e-12)


def test_ekf_recovers_long_dropped_depth_through_the_constraints():
    """A static shoulder whose depth is dropped for 5 s: KF holds a stale depth, the EKF corrects it."""
    rng = np.random.default_rng(4)
    truth = arm_track(150, DIMS)
    cfg = EKFConfig()
    z = noisy(truth, cfg, rng)
    s = INDEX["right_shoulder"]
    z[50:, s, 2] = truth[50:, s, 2] + 0.4  # depth corrupted first (the arm in front) ...
    z[60:, s, 2] = np.nan  # ... then dropped by the occlusion filter for the rest
    kf, ekf = ConstantVelocityKF(), ExtendedKalmanFilterCV(DIMS, cfg)
    e_kf = np.array([kf.step(zk, 0.1) for zk in z])
    e_ekf = np.array([ekf.step(zk, 0.1) for zk in z])
    err_kf = np.abs(e_kf[100:, s, 2] - truth[100:, s, 2]).mean()
    err_ekf = np.abs(e_ekf[100:, s, 2] - truth[100:, s, 2]).mean()
    assert err_ekf < 0.5 * err_kf, (err_kf, err_ekf)
    assert ekf.status[s] == TRACKING  # x, y still measured
    np.testing.assert_array_equal(ekf.velocity[s, 2], 0.0)  # depth held by the motion model


def test_ekf_skips_constraints_of_uninitialised_or_coincident_ends():
    ekf = ExtendedKalmanFilterCV(DIMS)
    z = np.full((NUM_LANDMARKS, 3), np.nan)
    z[INDEX["left_shoulder"]] = [0.0, 0.0, 2.0]
    z[INDEX["left_elbow"]] = [0.0, 0.0, 2.0]  # coincident with the shoulder: LUA undefined
    z[INDEX["right_shoulder"]] = [0.5, 0.0, 2.0]  # SW = 0.5 vs 0.332: pulled
    z[INDEX["right_elbow"], :2] = [0.5, 0.3]  # no depth yet: RUA skipped
    est = ekf.step(z, 0.1)
    np.testing.assert_array_equal(est[INDEX["left_elbow"]], z[INDEX["left_elbow"]])
    np.testing.assert_array_equal(est[INDEX["right_elbow"], :2], z[INDEX["right_elbow"], :2])
    assert np.isnan(est[INDEX["right_elbow"], 2])
    sw = np.linalg.norm(est[INDEX["left_shoulder"]] - est[INDEX["right_shoulder"]])
    assert DIMS.SW < sw < 0.5
    lengths = ekf.bone_lengths()
    assert np.isnan(lengths["RUA"]) and lengths["SW"] == pytest.approx(sw)


def test_ekf_status_and_lost_like_kf():
    ekf = ExtendedKalmanFilterCV(DIMS, EKFConfig(max_predict_s=0.3))
    truth = arm_track(10, DIMS)
    for zk in truth:
        ekf.step(zk, 0.1)
    assert (ekf.status == TRACKING).all()
    z = truth[-1].copy()
    z[INDEX["left_wrist"]] = np.nan
    z[INDEX["left_hip"]] = np.nan
    codes = []
    for _ in range(5):
        ekf.step(z, 0.1)
        codes.append((ekf.status[INDEX["left_wrist"]], ekf.status[INDEX["left_hip"]]))
    assert codes == [(PREDICTING, PREDICTING)] * 3 + [(LOST, LOST)] * 2
    np.testing.assert_array_equal(ekf.velocity[INDEX["left_wrist"]], 0.0)
    est = ekf.step(truth[-1], 0.1)
    np.testing.assert_allclose(est[INDEX["left_hip"]], truth[-1][INDEX["left_hip"]], atol=0)
    assert (ekf.status == TRACKING).all()


# ---------------------------------------------------------------------------------------------- properties
finite = st.floats(-3.0, 3.0, allow_nan=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    p_missing=st.floats(0.0, 0.9),
    scale=st.floats(0.001, 2.0),
)
def test_covariances_stay_symmetric_positive_and_estimates_finite(seed, p_missing, scale):
    rng = np.random.default_rng(seed)
    T = 40
    z = rng.normal(scale=scale, size=(T, NUM_LANDMARKS, 3)) + [0, 0, 2]
    z[rng.random((T, NUM_LANDMARKS, 3)) < p_missing] = np.nan
    kf, ekf = ConstantVelocityKF(), ExtendedKalmanFilterCV(DIMS)
    for zk in z:
        e1, e2 = kf.step(zk, 0.1), ekf.step(zk, 0.1)
        seen = kf.initialised
        assert np.isfinite(e1[seen]).all() and np.isnan(e1[~seen]).all()
        np.testing.assert_array_equal(np.isnan(e2), ~ekf.initialised)
        assert np.isfinite(e2[ekf.initialised]).all()
    assert (kf.position_variance[kf.initialised] > 0).all()
    P = ekf.arm_covariance
    assert np.abs(P - P.T).max() <= 1e-12 * max(1.0, np.abs(P).max())
    assert np.linalg.eigvalsh(0.5 * (P + P.T)).min() > -1e-12
