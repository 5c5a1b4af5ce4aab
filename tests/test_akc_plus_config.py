import math

import pytest

from akc_drake.core.akc_plus import AKCPlusConfig as ReExported
from akc_drake.core.akc_plus_config import AKCPlusConfig


def test_defaults_are_the_measurement_model_of_the_kf():
    c = AKCPlusConfig()
    assert ReExported is AKCPlusConfig
    assert c.depth_sigma_m == 0.05 and c.image_sigma_m == 0.01 and c.length_sigma_m == 0.01
    assert c.gate_sigma == 3.0 and c.recent_frames == 3.0
    assert c.sigma_shoulder_m == 0.01 and c.shoulder_alpha == 0.2 and c.arm_radius_m == 0.05
    assert AKCPlusConfig(sigma_shoulder_m=0).sigma_shoulder_m == 0.0  # 0 turns the held shoulder off
    assert isinstance(AKCPlusConfig(gate_frames=4).gate_frames, float)
    assert c.constrained_filter is False and AKCPlusConfig(constrained_filter=True).constrained_filter is True


@pytest.mark.parametrize("field, value", [("recent_frames", -1.0), ("gate_sigma", math.nan),
                                          ("sigma_temporal_m", 0.0), ("elbow_min_deg", 180.0),
                                          ("nis_alpha", True), ("shoulder_alpha", 0.0),
                                          ("shoulder_alpha", 1.5), ("sigma_shoulder_m", -0.01),
                                          ("arm_radius_m", -0.05), ("constrained_filter", 1),
                                          ("constrained_filter", "yes")])
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        AKCPlusConfig(**{field: value})
