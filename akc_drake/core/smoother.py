"""Zero-phase smoothing of recorded landmarks: a Rauch-Tung-Striebel (RTS) pass over our constant-velocity KF.

For offline data the forward Kalman filter (:class:`~akc_drake.core.kalman.ConstantVelocityKF`, eq. 1-3) lags the
motion: each estimate uses only the past. The RTS smoother adds a backward pass that uses the future as well,
so the estimate has no lag (zero phase) and a smaller variance. Same model as the KF, same parameters
(:class:`~akc_drake.core.kalman.KFConfig`: ``sigma_x/y/z``, ``accel_psd``, ``init_vel_var``, ``max_predict_s``);
per axis a 2-state (position, velocity) filter, all ``3 J`` axes at once.

Forward pass (as the KF, without its optional innovation gate and left/right swap handling)::

    x_{k|k-1} = A x_{k-1|k-1},        P_{k|k-1} = A P_{k-1|k-1} A^T + Q
    K = P_{k|k-1} H^T / (H P_{k|k-1} H^T + r),   x_{k|k} = x_{k|k-1} + K (z_k - H x_{k|k-1})

Backward pass (Rauch, Tung, Striebel 1965)::

    C_k = P_{k|k} A^T P_{k+1|k}^{-1}
    x_{k|N} = x_{k|k} + C_k (x_{k+1|N} - x_{k+1|k})
    P_{k|N} = P_{k|k} + C_k (P_{k+1|N} - P_{k+1|k}) C_k^T

Gaps: a missing measurement is a prediction, and the backward pass smooths it from both sides: the RTS pass
interpolates every gap between two measurements of an axis, however long (the prediction variance grows as
``q t^3``, so the measurement after the gap dominates: no run-away). This is where the smoother differs from the
real-time KF, which cannot see the end of a gap: beyond ``max_predict_s`` it holds the axis and re-initialises it
at the next measurement (:func:`kf_forward` with ``reinit_after_gap=True`` reproduces that exactly). Before an
axis's first measurement, and more than ``max_predict_s`` after its last one (extrapolation), it is NaN.
"""

from __future__ import annotations

import numpy as np

from akc_drake.core.kalman import KFConfig


def _check(z) -> np.ndarray:
    Z = np.asarray(z, dtype=float)
    if Z.ndim != 3 or Z.shape[2] != 3:
        raise ValueError(f"measurements must have shape (T, J, 3), got {Z.shape}")
    return Z


def kf_forward(z, dt: float, config: KFConfig | None = None, *, reinit_after_gap: bool = True):
    """The forward constant-velocity KF over a whole recording, keeping what the backward pass needs.

    Args:
        z: ``(T, J, 3)`` measurements, NaN where missing.
        dt: the frame period, seconds.
        config: the KF's parameters (default :class:`KFConfig`).
        reinit_after_gap: re-initialise an axis at a measurement after a gap longer than ``max_predict_s`` (the
            real-time KF's behaviour); False bridges every gap (the smoother's forward pass).

    Returns:
        dict of ``(T, 3J)`` arrays ``p, v, Ppp, Ppv, Pvv`` (filtered), ``pp, vp, Pppp, Pppv, Ppvv`` (predicted,
        i.e. before fusing frame k), and ``(T, 3J)`` bool ``start`` (the axis was (re)initialised at k) and
        ``valid`` (the axis has an estimate at k: within ``max_predict_s`` of its last measurement).
    """
    cfg = KFConfig() if config is None else config
    Z = _check(z)
    dt = float(dt)
    if not (dt > 0 and np.isfinite(dt)):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    T, J, _ = Z.shape
    N = 3 * J
    zf = Z.reshape(T, N)
    r = np.tile(cfg.r, J)
    q = np.tile(np.asarray(cfg.accel_psd, dtype=float), J)
    Qpp, Qpv, Qvv = q * dt**3 / 3.0, q * dt**2 / 2.0, q * dt
    out = {k: np.full((T, N), np.nan) for k in ("p", "v", "Ppp", "Ppv", "Pvv", "pp", "vp", "Pppp", "Pppv", "Ppvv")}
    start = np.zeros((T, N), dtype=bool)
    valid = np.zeros((T, N), dtype=bool)
    p, v = np.zeros(N), np.zeros(N)
    Ppp, Ppv, Pvv = np.zeros(N), np.zeros(N), np.zeros(N)
    age = np.full(N, np.inf)
    limit = cfg.max_predict_s + 1e-9
    for k in range(T):
        m = np.isfinite(zf[k])
        # Prediction x = A x, P = A P A^T + Q (per axis 2x2, written out).
        pp = p + dt * v
        Pp_pp = Ppp + 2 * dt * Ppv + dt * dt * Pvv + Qpp
        Pp_pv = Ppv + dt * Pvv + Qpv
        Pp_vv = Pvv + Qvv
        age = age + dt
        # never measured (age inf), or (real-time KF) a gap longer than max_predict_s
        init = m & (age > limit) if reinit_after_gap else m & ~np.isfinite(age)
        use = m & ~init
        out["pp"][k], out["vp"][k] = pp, v
        out["Pppp"][k], out["Pppv"][k], out["Ppvv"][k] = Pp_pp, Pp_pv, Pp_vv
        # Update with H = [1, 0]: S = P_pp + r, K = [P_pp, P_pv] / S.
        S = Pp_pp + r
        y = np.where(use, zf[k] - pp, 0.0)
        Kp, Kv = np.where(use, Pp_pp / S, 0.0), np.where(use, Pp_pv / S, 0.0)
        p, v = pp + Kp * y, v + Kv * y
        Ppp, Ppv, Pvv = (1 - Kp) * Pp_pp, (1 - Kp) * Pp_pv, Pp_vv - Kv * Pp_pv
        # (Re)initialisation: p = z, v = 0, P = diag(r, init_vel_var).
        p = np.where(init, zf[k], p)
        v = np.where(init, 0.0, v)
        Ppp = np.where(init, r, Ppp)
        Ppv = np.where(init, 0.0, Ppv)
        Pvv = np.where(init, cfg.init_vel_var, Pvv)
        age = np.where(m, 0.0, age)
        start[k] = init
        valid[k] = age <= limit
        out["p"][k], out["v"][k] = p, v
        out["Ppp"][k], out["Ppv"][k], out["Pvv"][k] = Ppp, Ppv, Pvv
    out["start"], out["valid"] = start, valid
    return out


def rts_smooth(z, dt: float, config: KFConfig | None = None) -> np.ndarray:
    """Zero-phase RTS smoothing of recorded landmarks (see the module docstring).

    Args:
        z: ``(T, J, 3)`` measurements in any fixed frame (e.g. the occlusion filter's output), NaN where missing.
        dt: the frame period, seconds.
        config: the KF's parameters (default :class:`KFConfig`, the pipeline's).

    Returns:
        ``(T, J, 3)`` smoothed positions, NaN where the axis has no estimate.
    """
    Z = _check(z)
    f = kf_forward(Z, dt, config, reinit_after_gap=False)
    T, J, _ = Z.shape
    ps, vs = f["p"].copy(), f["v"].copy()
    Pss, Psv, Pvs = f["Ppp"].copy(), f["Ppv"].copy(), f["Pvv"].copy()
    for k in range(T - 2, -1, -1):
        # Smooth k from k+1 only where k+1 continues the same track (not its first measurement).
        cont = ~f["start"][k + 1]
        # P_{k+1|k} inverse (2x2): [[a, b], [b, c]]^-1 = [[c, -b], [-b, a]] / det.
        a, b, c = f["Pppp"][k + 1], f["Pppv"][k + 1], f["Ppvv"][k + 1]
        det = a * c - b * b
        ia, ib, ic = c / det, -b / det, a / det
        # P_{k|k} A^T with A = [[1, dt], [0, 1]]: [[Ppp + dt Ppv, Ppv], [Ppv + dt Pvv, Pvv]].
        Ppp, Ppv, Pvv = f["Ppp"][k], f["Ppv"][k], f["Pvv"][k]
        m11, m12 = Ppp + dt * Ppv, Ppv
        m21, m22 = Ppv + dt * Pvv, Pvv
        # C_k = P_{k|k} A^T P_{k+1|k}^{-1}
        C11, C12 = m11 * ia + m12 * ib, m11 * ib + m12 * ic
        C21, C22 = m21 * ia + m22 * ib, m21 * ib + m22 * ic
        # x_{k|N} = x_{k|k} + C_k (x_{k+1|N} - x_{k+1|k})
        dp, dv = ps[k + 1] - f["pp"][k + 1], vs[k + 1] - f["vp"][k + 1]
        # P_{k|N} = P_{k|k} + C_k (P_{k+1|N} - P_{k+1|k}) C_k^T
        D11, D12, D22 = Pss[k + 1] - a, Psv[k + 1] - b, Pvs[k + 1] - c
        with np.errstate(invalid="ignore", divide="ignore"):
            new_p = f["p"][k] + C11 * dp + C12 * dv
            new_v = f["v"][k] + C21 * dp + C22 * dv
            n11 = Ppp + C11 * (C11 * D11 + C12 * D12) + C12 * (C11 * D12 + C12 * D22)
            n12 = Ppv + C11 * (C21 * D11 + C22 * D12) + C12 * (C21 * D12 + C22 * D22)
            n22 = Pvv + C21 * (C21 * D11 + C22 * D12) + C22 * (C21 * D12 + C22 * D22)
        ps[k] = np.where(cont, new_p, ps[k])
        vs[k] = np.where(cont, new_v, vs[k])
        Pss[k], Psv[k], Pvs[k] = np.where(cont, n11, Pss[k]), np.where(cont, n12, Psv[k]), np.where(cont, n22, Pvs[k])
    # No estimate before an axis's first measurement, nor beyond max_predict_s after its last one.
    seen = np.maximum.accumulate(f["start"], axis=0)
    measured = np.isfinite(Z.reshape(T, -1))
    ahead = np.maximum.accumulate(measured[::-1], axis=0)[::-1]  # a measurement at or after k
    ok = seen & (f["valid"] | ahead)
    out = np.where(ok, ps, np.nan)
    return out.reshape(T, J, 3)


def smoothed_stages(accepted, dt: float, dims=None, config: KFConfig | None = None, weights=None) -> dict:
    """The pipeline's S3b and S4 on a whole recording with the RTS smoother in place of the forward KF.

    Args:
        accepted: ``(T, 12, 3)`` the occlusion filter's output (``poses.npz`` field ``accepted``).
        dt: the frame period, seconds.
        dims: the calibrated :class:`~akc_drake.core.skeleton.BodyDimensions`; None skips the correction.
        config: the KF parameters.
        weights: AKC weights (default: the paper's Wb).

    Returns:
        ``{"filtered": (T, 12, 3)}`` and, with ``dims``, ``"corrected"``: AKC applied frame by frame to the
        smoothed landmarks (AKC itself is causal; its input no longer lags).
    """
    out = {"filtered": rts_smooth(accepted, dt, config)}
    if dims is not None:
        from akc_drake.core.akc import ArmKinematicCorrector

        akc = ArmKinematicCorrector(dims, weights)
        out["corrected"] = np.stack([akc.correct(p).pose for p in out["filtered"]])
    return out


def rts_gain(truth, forward: dict, smoothed: dict, joints=None) -> dict:
    """RMSE (cm) of the forward and the smoothed stages against the truth, on the frames where both have an estimate.

    Args:
        truth: ``(T, 12, 3)`` ground truth (NaN on frames to leave out).
        forward: stage -> ``(T, 12, 3)`` from the forward KF (``filtered``, ``corrected``).
        smoothed: the same stages from :func:`smoothed_stages`.
        joints: landmark names (default: the six arm joints).

    Returns:
        per stage ``{"forward_rmse_cm", "rts_rmse_cm", "gain_percent", "coverage", "joints"}``: the RMSEs are the
        mean over the joints (and axes) of each joint's RMSE on the frames where truth, forward and smoothed all
        have the joint; ``coverage`` is the share of the forward estimates the smoother also has (it has none more
        than ``max_predict_s`` after an axis's last measurement, where the KF holds a stale value); ``joints``
        lists the joints that had such frames.
    """
    from akc_drake.core.metrics import rmse_per_axis
    from akc_drake.core.skeleton import ARM_JOINTS, INDEX

    joints = ARM_JOINTS if joints is None else joints
    tr_all = np.asarray(truth, dtype=float)
    out = {}
    for stage in smoothed:
        if stage not in forward:
            continue
        f_all, s_all = np.asarray(forward[stage], dtype=float), np.asarray(smoothed[stage], dtype=float)
        rf, rs, used, have_f, have_both = [], [], [], 0, 0
        for name in joints:
            j = INDEX[name]
            tr = tr_all[:, j]
            okf = np.isfinite(f_all[:, j]).all(axis=1) & np.isfinite(tr).all(axis=1)
            both = okf & np.isfinite(s_all[:, j]).all(axis=1)
            have_f, have_both = have_f + int(okf.sum()), have_both + int(both.sum())
            if not both.any():
                continue
            rf.append(np.mean(rmse_per_axis(f_all[both, j], tr[both])[0]))
            rs.append(np.mean(rmse_per_axis(s_all[both, j], tr[both])[0]))
            used.append(name)
        f_cm = 100.0 * float(np.mean(rf)) if rf else float("nan")
        s_cm = 100.0 * float(np.mean(rs)) if rs else float("nan")
        out[stage] = {
            "forward_rmse_cm": f_cm,
            "rts_rmse_cm": s_cm,
            "gain_percent": 100.0 * (f_cm - s_cm) / f_cm if f_cm > 0 else None,
            "coverage": have_both / have_f if have_f else None,
            "joints": used,
        }
    return out
