import numpy as np
import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_state import STATE_SIZE
from akc_drake.core.skeleton import INDEX
from tests.test_akc_plus import LE, LS, LW, arm_pose, kf_var


def test_state_round_trips_with_the_running_nis():
    p, dims = arm_pose()
    f = p.copy()
    f[LW, 2] += 0.06
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(3):
        out = akc.correct(f, measured=p, variance=kf_var()).pose
    v = akc.get_state_vector()
    assert v.shape == (STATE_SIZE,) and v[36:54].max() > 1.0  # the lagging wrist's NIS
    # The left forearm, wrist detected (our output's: the reading fused with the lagging filter, within 1 mm of it).
    np.testing.assert_allclose(v[54:57], out[LW] - out[LE], atol=1e-9)
    np.testing.assert_allclose(v[54:57], p[LW] - p[LE], atol=1e-3)
    assert v[57] == 0.0
    np.testing.assert_allclose(v[62:65], out[LE] - out[LS], atol=1e-9)  # the left upper arm, elbow detected
    assert v[65] == 0.0
    np.testing.assert_allclose(v[78:81], out[LE] - out[LS], atol=1e-9)  # the upper arm the held forearm turns with
    np.testing.assert_allclose(v[78:81], p[LE] - p[LS], atol=1e-3)
    assert list(v[103:105]) == [0.0, 0.0]  # (no misread frames since either forearm was taken)
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    np.testing.assert_array_equal(other.correct(f, p, kf_var()).pose, akc.correct(f, p, kf_var()).pose)
    bad = v.copy()
    bad[53] = -1.0
    with pytest.raises(ValueError, match="NIS"):
        other.set_state_vector(bad)
    bad = v.copy()
    bad[57] = -1.0
    with pytest.raises(ValueError, match="blind-frame count"):
        other.set_state_vector(bad)
    bad = v.copy()
    bad[65] = -1.0
    with pytest.raises(ValueError, match="blind-elbow frame count"):
        other.set_state_vector(bad)
    for k in (-1.0, np.nan):
        bad = v.copy()
        bad[104] = k
        with pytest.raises(ValueError, match=r"misread-frame count \[104\]"):
            other.set_state_vector(bad)
    with pytest.raises(ValueError, match="variance"):
        akc.correct(p, measured=p, variance=np.zeros((3, 3)))


def test_state_round_trips_while_a_held_forearm_turns_with_its_upper_arm():
    # Mid-swing, the wrist lost: a corrector restored from the state vector goes on exactly as the original, and a
    # forearm that no longer turns (NaN) stays so.
    from tests.test_akc_plus import _swing_with_the_wrist_lost

    for elbow_lost_at in (None, 1):
        akc, dims, out, truth, f = _swing_with_the_wrist_lost(elbow_lost_at=elbow_lost_at, frames=2)
        v = akc.get_state_vector()
        assert np.isfinite(v[78:81]).all() == (elbow_lost_at is None)
        other = ArmKinematicCorrectorPlus(dims)
        other.set_state_vector(v)
        np.testing.assert_array_equal(other.get_state_vector(), v)
        m = truth.copy()
        m[[LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan  # (the wrist and the hand lost)
        var = kf_var()
        var[LW] = 0.09
        np.testing.assert_array_equal(other.correct(f, m, var).pose, akc.correct(f, m, var).pose)


def test_state_round_trips_while_a_shoulder_is_held_on_the_other_one():
    # The left shoulder read 30 cm in front from one frame to the next (``_shoulder_jumped``): the shoulders'
    # depth difference, the frames held, the last measured depth and the frames since are in [93:101], and a
    # corrector restored from them holds the shoulder exactly as the original.
    from tests.test_akc_plus import settled_corrector

    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    f = p.copy()
    f[LS] *= 1.7 / 2.0
    f[[INDEX["left_hip"], INDEX["right_hip"]], 2] -= 0.3  # (the hips read as far in front: no torso vote)
    m = f.copy()
    m[[LE, LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan
    for _ in range(2):
        akc.correct(f, measured=m, variance=kf_var())
    v = akc.get_state_vector()
    np.testing.assert_allclose(v[93:101], [0.0, 2.0, 1.7, 0.0, 0.0, 0.0, 2.0, 0.0], atol=1e-12)
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    np.testing.assert_array_equal(other.correct(f, m, kf_var()).pose, akc.correct(f, m, kf_var()).pose)
    assert np.linalg.norm(akc.correct(f, m, kf_var()).pose[LS] - p[LS]) < 0.01
    bad = v.copy()
    bad[94] = -1.0
    with pytest.raises(ValueError, match="shoulder-pair frame count"):
        other.set_state_vector(bad)


def test_state_round_trips_the_elbows_remembered_readings():
    # [101:103]: per side the elbow's depth read where a rule put the elbow behind it (NaN: none). A corrector
    # restored from the vector remembers it; an infinite reading is no state.
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    v = akc.get_state_vector()
    assert np.isnan(v[101:103]).all()
    v[101] = 1.92
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    other.reset()
    assert np.isnan(other.get_state_vector()[101:103]).all()
    v[102] = np.inf
    with pytest.raises(ValueError, match="elbow readings"):
        other.set_state_vector(v)


def test_state_round_trips_the_depth_reading_noise():
    # After an EKF: per side and joint the last depth residual and the reading noise. Restored, a corrector goes on
    # exactly as the original; a negative noise or an infinite residual is refused, naming the entries.
    from akc_drake.core.akc_plus_config import AKCPlusConfig

    p, dims = arm_pose()
    rng = np.random.default_rng(0)
    akc = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=True))
    fresh = akc.get_state_vector()
    assert np.isnan(fresh[105:117:2]).all() and (fresh[106:117:2] == 0.015**2).all()  # (assumed before any frame)
    for _ in range(4):
        m = p.copy()
        m[:, 2] += rng.normal(0.0, 0.01, len(p))
        akc.correct(p, measured=m, variance=kf_var())
    v = akc.get_state_vector()
    k = 2  # (the left elbow's pair: side 0, joint 1)
    assert v[105 + k] == pytest.approx(m[LE, 2] - p[LE, 2], abs=1e-15)
    assert 0.0 < v[106 + k] < 0.015**2  # measured: under the assumed noise
    other = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=True))
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    np.testing.assert_array_equal(other.correct(p, m, kf_var()).pose, akc.correct(p, m, kf_var()).pose)
    for i, bad_value in ((106, -1e-4), (108, np.nan), (105, np.inf)):
        bad = v.copy()
        bad[i] = bad_value
        with pytest.raises(ValueError, match=r"depth residuals \[105:117:2\]"):
            other.set_state_vector(bad)


def test_state_round_trips_the_elbows_learnt_offset():
    # Per side the running means the elbow's offset is learnt from (a prior worth half a straight arm at the
    # projections' offset variance). Restored, a corrector goes on exactly as the original; a negative mean of
    # c^2 or a non-finite mean is refused, naming the entries.
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    np.testing.assert_array_equal(akc.get_state_vector()[117:121], [0.25e-4, 0.5, 0.25e-4, 0.5])
    m = p.copy()
    m[LE] += 0.02 * (p[LS] - p[LE]) / np.linalg.norm(p[LS] - p[LE])  # (the elbow's landmark 2 cm up the arm)
    for _ in range(5):
        akc.correct(m, measured=m, variance=kf_var())
    v = akc.get_state_vector()
    assert v[117] > 0.25e-4 and list(v[119:121]) != [0.25e-4, 0.5]  # (the left one learnt; the right too: exact arm)
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    np.testing.assert_array_equal(other.correct(m, m, kf_var()).pose, akc.correct(m, m, kf_var()).pose)
    for i, bad_value in ((118, -0.1), (117, np.nan), (120, np.inf)):
        bad = v.copy()
        bad[i] = bad_value
        with pytest.raises(ValueError, match=r"elbow offset's means \[117:121\]"):
            other.set_state_vector(bad)
