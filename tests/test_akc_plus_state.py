import numpy as np
import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_state import STATE_SIZE
from tests.test_akc_plus import LE, LS, LW, arm_pose, kf_var


def test_state_round_trips_with_the_running_nis():
    p, dims = arm_pose()
    f = p.copy()
    f[LW, 2] += 0.06
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(3):
        akc.correct(f, measured=p, variance=kf_var())
    v = akc.get_state_vector()
    assert v.shape == (STATE_SIZE,) and v[36:54].max() > 1.0  # the lagging wrist's NIS
    np.testing.assert_allclose(v[54:57], p[LW] - p[LE], atol=1e-9)  # the left forearm, wrist detected
    assert v[57] == 0.0
    np.testing.assert_allclose(v[62:65], p[LE] - p[LS], atol=1e-9)  # the left upper arm, elbow detected
    assert v[65] == 0.0
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
    with pytest.raises(ValueError, match="variance"):
        akc.correct(p, measured=p, variance=np.zeros((3, 3)))
