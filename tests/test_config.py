import pytest

from akc_drake.config import PipelineConfig, dump_config, load_config
from akc_drake.errors import UserError


def test_yaml_round_trip(tmp_path):
    cfg = PipelineConfig(motion="I", cycles=3, filter="EKF", corrector="COIK", dims={"LUA": 0.3, "LLA": 0.28,
                         "RUA": 0.3, "RLA": 0.27, "SW": 0.33})
    f = tmp_path / "c.yaml"
    f.write_text(dump_config(cfg))
    back = load_config(f)
    assert back == cfg


def test_yaml_errors_name_file_and_field(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("filtr: EKF\n")
    with pytest.raises(UserError, match=r"bad.yaml.*filtr"):
        load_config(f)
    f.write_text("cycles: many\n")
    with pytest.raises(UserError, match="bad.yaml"):
        load_config(f)
    f.write_text("filter: UKF\n")
    with pytest.raises(UserError, match=r"bad.yaml: config.filter must be one of"):
        load_config(f)
    f.write_text("dims: {LUA: -1, LLA: 0.3, RUA: 0.3, RLA: 0.3, SW: 0.3}\n")
    with pytest.raises(UserError, match="config.dims.*LUA"):
        load_config(f)
    with pytest.raises(UserError, match="not found"):
        load_config(tmp_path / "nope.yaml")
