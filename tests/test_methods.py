"""The method runner's plumbing of the filter's covariance into AKC+, and of correctors of your own
(evaluation/methods.py)."""

import sys

import numpy as np
import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_config import AKCPlusConfig
from akc_drake.core.kalman import ConstantVelocityKF
from akc_drake.core.skeleton import BodyDimensions
from akc_drake.evaluation.methods import MethodOptions, MethodRunner, run_akc, run_filter
from tests.test_evaluation import synthetic_session


def test_run_filter_records_the_posterior_variance_of_every_step():
    s = synthetic_session("I", cycles=1, seed=3)
    z = s.raw.copy()
    z[10:20, 2, 2] = np.nan  # a lost depth: its variance grows while the others stay
    var = np.empty_like(z)
    est, dt = run_filter(ConstantVelocityKF(), z, s.t, var)
    again, _ = run_filter(ConstantVelocityKF(), z, s.t)
    np.testing.assert_array_equal(est, again)  # recording does not change the filter
    kf = ConstantVelocityKF()
    steps = np.diff(s.t, prepend=s.t[0] - (s.t[1] - s.t[0]))
    for k in range(15):
        kf.step(z[k], float(steps[k]))
    np.testing.assert_allclose(var[14], kf.position_variance, rtol=0, atol=0)
    assert np.all(np.diff(var[10:20, 2, 2]) > 0) and var[19, 2, 2] > 4 * var[9, 2, 2]
    assert dt.shape == (s.num_frames,)


@pytest.mark.parametrize("filt, refit", [("KF", False), ("EKF", True)])
def test_akc_plus_method_gets_the_filter_variance(filt, refit):
    """AKC+ gets the filter's variance; after an EKF, whose posterior holds bone lengths, it refits it
    (``constrained_filter``), after the KF not."""
    s = synthetic_session("II" if refit else "I", cycles=1, seed=5 if refit else 4)
    dims = BodyDimensions.paper_participant()
    runner = MethodRunner(s, dims)
    res = runner.run(f"AKC+({filt})")
    est, _ = runner.filtered(filt)
    var = runner.filter_variance(filt)
    assert var.shape == est.shape and np.all(var[np.isfinite(est)] > 0)
    accepted, _ = runner.occlusion()
    want, _, _ = run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=refit)), est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    # Without the variance (KF), or without the refit (EKF), the output differs: each is used.
    other = (run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig()), est, accepted, var) if refit
             else run_akc(ArmKinematicCorrectorPlus(dims), est, accepted))[0]
    assert not np.array_equal(np.nan_to_num(other), np.nan_to_num(want))


def test_akc_plus_settings_reach_the_method():
    """``MethodOptions.akc_plus_config`` as plain data (what ``--akc-plus`` and the workers carry): a switch it sets
    wins over the one made from the filter, and the other fields reach the corrector."""
    s = synthetic_session("II", cycles=1, seed=5)
    dims = BodyDimensions.paper_participant()
    settings = {"constrained_filter": False, "gate_sigma": 2.0}
    runner = MethodRunner(s, dims, options=MethodOptions(akc_plus_config=settings))
    res = runner.run("AKC+(EKF)")
    est, _ = runner.filtered("EKF")
    accepted, _ = runner.occlusion()
    var = runner.filter_variance("EKF")
    want, _, _ = run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig(gate_sigma=2.0, constrained_filter=False)),
                         est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    default = MethodRunner(s, dims).run("AKC+(EKF)").estimates
    assert not np.array_equal(np.nan_to_num(default), np.nan_to_num(want))


# ------------------------------------------------------------------------------------------- your own corrector
_OWN = '''
import numpy as np

CALLS = []


class Shift:
    """Moves every landmark 1 cm in x; records what it is given."""

    def __init__(self, dims, filter_kind, period_s):
        CALLS.append(("init", dims, filter_kind, period_s))

    def reset(self):
        CALLS.append(("reset",))

    def correct(self, pose, measured, variance):
        CALLS.append(("correct", pose.copy(), measured.copy(), variance.copy()))
        return pose + np.array([0.01, 0.0, 0.0])


class Result:
    def __init__(self, pose):
        self.pose = pose


def wrapped(dims, filter_kind, period_s):  # returns an object with a pose, no reset
    class C:
        def correct(self, pose, measured, variance):
            return Result(pose - np.array([0.0, 0.02, 0.0]))
    return C()


NOT_CALLABLE = 3


class Flat:
    def __init__(self, dims, filter_kind, period_s):
        pass

    def correct(self, pose, measured, variance):
        return pose[0]  # (3,): would broadcast into every landmark
'''


@pytest.fixture()
def own_file(tmp_path):
    f = tmp_path / "own_corrector.py"
    f.write_text(_OWN)
    return f


def test_your_own_corrector_runs_as_a_method_and_gets_what_akc_plus_gets(own_file):
    from akc_drake.evaluation.methods import load_corrector, parse_correctors, parse_method, run_methods

    own = parse_correctors([f"SHIFT={own_file}:Shift", f"WRAP={own_file}:wrapped"])
    assert own == {"SHIFT": f"{own_file.resolve()}:Shift", "WRAP": f"{own_file.resolve()}:wrapped"}
    spec = parse_method(" SHIFT ( EKF ) ", own)
    assert (spec.name, spec.filter, spec.corrector, spec.occlusion) == ("SHIFT(EKF)", "EKF", "SHIFT", True)
    with pytest.raises(ValueError, match=r"unknown method 'SHIFT\(KF\)'"):
        parse_method("SHIFT(KF)")  # (not without the corrector's name)
    s = synthetic_session("I", cycles=1, seed=4)
    dims = BodyDimensions.paper_participant()
    module = sys.modules[load_corrector(own["SHIFT"]).__module__]  # (loaded once per process)
    module.CALLS.clear()
    out = run_methods(["KF", "SHIFT(KF)", "WRAP(EKF)"], s, dims, options=MethodOptions(correctors=own))
    runner = MethodRunner(s, dims)
    kf, _ = runner.filtered("KF")
    ekf, _ = runner.filtered("EKF")
    np.testing.assert_array_equal(out["SHIFT(KF)"].estimates, kf + np.array([0.01, 0.0, 0.0]))
    np.testing.assert_array_equal(out["WRAP(EKF)"].estimates, ekf - np.array([0.0, 0.02, 0.0]))
    assert out["SHIFT(KF)"].stage_time_s["corrector"].shape == (s.num_frames,)
    # The factory got the dimensions, the filter and the period; correct got the filter's pose, the occlusion
    # filter's measurement and the filter's variance, every frame.
    init, reset, *frames = module.CALLS
    assert init == ("init", dims, "KF", pytest.approx(s.dt)) and reset == ("reset",)
    assert len(frames) == s.num_frames
    accepted, _ = runner.occlusion()
    var = runner.filter_variance("KF")
    k = s.num_frames // 2
    np.testing.assert_array_equal(frames[k][1], kf[k])
    np.testing.assert_array_equal(frames[k][2], accepted[k])
    np.testing.assert_array_equal(frames[k][3], var[k])
    # A pose of the wrong shape is an error naming the corrector and the frame, not a broadcast.
    flat = MethodRunner(s, dims, options=MethodOptions(correctors=parse_correctors(f"FLAT={own_file}:Flat")))
    with pytest.raises(ValueError, match=r"Flat.correct returned a pose of shape \(3,\) at frame 0"):
        flat.run("FLAT(KF)")


def test_a_wrong_corrector_is_named_before_a_run(own_file, tmp_path):
    from akc_drake.evaluation.methods import parse_correctors

    cases = {
        "SHIFT": "expected NAME=package.module:attribute",
        f"SHIFT={own_file}": "expected package.module:attribute or file.py:attribute",
        f"AKC+={own_file}:Shift": "is a built-in method's",
        f"KF={own_file}:Shift": "is a built-in method's",
        f"2X={own_file}:Shift": "a letter first",
        f"A={own_file}:Shift,A={own_file}:wrapped": "given more than once",
        f"A={own_file}:Missing": "has no 'Missing'",
        f"A={own_file}:NOT_CALLABLE": "is not callable",
        f"A={tmp_path / 'nothing.py'}:Shift": "no such file",
        "A=akc_drake.no_such_module:f": "cannot import 'akc_drake.no_such_module'",
    }
    for text, message in cases.items():
        with pytest.raises(ValueError, match=message):
            parse_correctors(text)
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('boom')\n")
    with pytest.raises(ValueError, match="fails to load .RuntimeError: boom"):
        parse_correctors(f"B={broken}:f")
    # A module path works as a file does.
    assert parse_correctors("LEN=akc_drake.evaluation.methods:make_akc") == {
        "LEN": "akc_drake.evaluation.methods:make_akc"}


def test_the_example_corrector_keeps_the_calibrated_lengths():
    from pathlib import Path

    from akc_drake.core.metrics import arm_length_range
    from akc_drake.core.skeleton import INDEX
    from akc_drake.evaluation.methods import parse_correctors

    example = Path(__file__).resolve().parents[1] / "examples" / "segment_lengths.py"
    own = parse_correctors(f"LEN={example}:SegmentLengths")
    s = synthetic_session("II", cycles=1, seed=6)
    dims = BodyDimensions.paper_participant()
    runner = MethodRunner(s, dims, options=MethodOptions(correctors=own))
    est = runner.run("LEN(KF)").estimates
    kf, _ = runner.filtered("KF")
    arms = [INDEX[f"{side}_{j}"] for side in ("left", "right") for j in ("shoulder", "elbow", "wrist")]
    ok = np.isfinite(kf[:, arms]).all(axis=(1, 2))
    assert ok.sum() > 0.8 * s.num_frames
    rng = arm_length_range(est[ok])
    assert max(rng.values()) < 1e-12
    for side, upper in (("left", dims.LUA), ("right", dims.RUA)):
        s_, e = INDEX[f"{side}_shoulder"], INDEX[f"{side}_elbow"]
        np.testing.assert_allclose(np.linalg.norm(est[ok, e] - est[ok, s_], axis=1), upper, rtol=0, atol=1e-12)
        # The shoulder is the filter's, and the elbow stays on the filter's upper-arm direction.
        np.testing.assert_array_equal(est[:, s_], kf[:, s_])
        d_est, d_kf = est[ok, e] - est[ok, s_], kf[ok, e] - kf[ok, s_]
        cos = np.sum(d_est * d_kf, axis=1) / np.linalg.norm(d_est, axis=1) / np.linalg.norm(d_kf, axis=1)
        np.testing.assert_allclose(cos, 1.0, atol=1e-12)
