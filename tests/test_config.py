import pytest

from akc_drake.config import (
    DEFAULT_CAMERA,
    TELEOP_FILTER_SETTINGS,
    ArmLimitsConfig,
    CameraConfig,
    PipelineConfig,
    depth_noise_model,
    describe_camera,
    describe_depth_noise,
    dump_config,
    load_config,
    parse_akc_plus,
    parse_arm_limits,
    parse_camera,
    parse_depth_noise,
    parse_filter_settings,
)
from akc_drake.errors import UserError


def test_yaml_round_trip(tmp_path):
    cfg = PipelineConfig(motion="I", cycles=3, filter="EKF", corrector="COIK", dims={"LUA": 0.3, "LLA": 0.28,
                         "RUA": 0.3, "RLA": 0.27, "SW": 0.33}, akc_plus={"gate_sigma": 2.5, "constrained_filter": 0.0},
                         arm_limits=ArmLimitsConfig(acceleration=[9.0] * 7, jerk=[4000.0]))
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
    f.write_text("akc_plus: {gate_sgima: 2.5}\n")
    with pytest.raises(UserError, match=r"bad.yaml: config.akc_plus: unknown AKC\+ setting.*'gate_sgima'"):
        load_config(f)
    f.write_text("arm_limits: {jerk: [5000, -1]}\n")
    with pytest.raises(UserError, match=r"bad.yaml: config.arm_limits: jerk must hold positive numbers"):
        load_config(f)
    f.write_text("akc_plus: {nis_alpha: 0}\n")
    with pytest.raises(UserError, match=r"config.akc_plus: .*nis_alpha must be in \(0, 1\]"):
        load_config(f)


def test_akc_plus_settings_from_the_command_line(tmp_path):
    assert parse_akc_plus("gate_sigma=2.5, nis_alpha=0.1,constrained_filter=TRUE") == {
        "gate_sigma": 2.5, "nis_alpha": 0.1, "constrained_filter": True}
    f = tmp_path / "plus.json"
    f.write_text('{"xy_tol_m": 0.02, "constrained_filter": false}')
    assert parse_akc_plus(str(f)) == {"xy_tol_m": 0.02, "constrained_filter": False}
    for text, match in [("gate_sigma", "is not field=value"), ("gate_sigma=two", "'two' is not a number"),
                        (" , ", "empty"), ("jump=0.1", "unknown AKC\\+ setting.*'jump'.*jump_m"),
                        ("hand_length_m=-0.08", "hand_length_m must be a finite number >= 0"),
                        (str(tmp_path / "none.json"), "cannot read it"), (str(f) + "x.json", "cannot read it")]:
        with pytest.raises(UserError, match="^--akc-plus.*" + match):
            parse_akc_plus(text)
    f.write_text("[1, 2]")
    with pytest.raises(UserError, match="expected a JSON object"):
        parse_akc_plus(str(f))
    f.write_text("{nope")
    with pytest.raises(UserError, match="not valid JSON"):
        parse_akc_plus(str(f))


def test_arm_limits_resolve_against_the_model_defaults():
    acc, jerk = [15.0] * 4 + [20.0] * 3, [7500.0] * 4 + [1e4] * 3
    assert ArmLimitsConfig().resolve(acc, jerk) == (acc, jerk)  # empty: the model's
    assert ArmLimitsConfig(acceleration=[5]).resolve(acc, jerk) == ([5.0] * 7, jerk)  # one number: every joint
    own = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    assert ArmLimitsConfig(acceleration=[9.0], jerk=own).resolve(acc, jerk) == ([9.0] * 7, own)
    assert ArmLimitsConfig(enabled=False, acceleration=[5.0]).resolve(acc, jerk) is False
    with pytest.raises(UserError, match=r"config.arm_limits: acceleration must be empty .* or 7 .*got 2"):
        ArmLimitsConfig(acceleration=[5.0, 6.0]).resolve(acc, jerk)
    for bad in ([0.0], [float("nan")], [float("inf")], [True], ["5"]):
        with pytest.raises(UserError, match="jerk must hold positive numbers"):
            ArmLimitsConfig(jerk=bad).resolve(acc, jerk)


def test_arm_limits_from_the_command_line(tmp_path):
    assert parse_arm_limits("off") == ArmLimitsConfig(enabled=False)
    assert parse_arm_limits("acceleration=10, jerk=5e3") == ArmLimitsConfig(acceleration=[10.0], jerk=[5000.0])
    assert parse_arm_limits("jerk=5000") == ArmLimitsConfig(jerk=[5000.0])
    f = tmp_path / "arm.json"
    f.write_text('{"acceleration": [8, 8, 8, 8, 12, 12, 12], "enabled": true}')
    assert parse_arm_limits(str(f)) == ArmLimitsConfig(acceleration=[8, 8, 8, 8, 12, 12, 12])
    for text, match in [("accel=3", r"unknown field\(s\) accel \(known: enabled, acceleration, jerk; or off\)"),
                        ("jerk=x", "'x' is not a number"), ("acceleration=-1", "acceleration must hold positive"),
                        ("enabled=maybe", r"'maybe' is not a number \(nor true / false\)"),
                        ("enabled=1", "enabled must be true or false, got 1.0"), ("on", "is not field=value")]:
        with pytest.raises(UserError, match="^--arm-limits: .*" + match):
            parse_arm_limits(text)
    f.write_text('{"enabled": "yes"}')
    with pytest.raises(UserError, match="enabled must be true or false"):
        parse_arm_limits(str(f))


def test_gate_speed_floor_resolves_and_loads_from_yaml(tmp_path):
    """``gate_speed_m_s``: negative is the teleop default (6 m/s), 0 turns the floor off, a YAML key sets it, and
    the diagram's filter gets it only when its gate is on."""
    from pydrake.systems.framework import DiagramBuilder

    from akc_drake import diagrams
    from akc_drake.config import TELEOP_GATE_SPEED_M_S
    from akc_drake.core.skeleton import BodyDimensions

    assert PipelineConfig().resolved_gate_speed_m_s() == TELEOP_GATE_SPEED_M_S == 6.0
    assert PipelineConfig(gate_speed_m_s=0.0).resolved_gate_speed_m_s() is None
    path = tmp_path / "run.yaml"
    path.write_text("gate_speed_m_s: 3.5\n")
    assert load_config(str(path)).resolved_gate_speed_m_s() == 3.5
    with pytest.raises(UserError, match="gate_speed_m_s"):
        PipelineConfig(gate_speed_m_s=float("nan")).validate()

    def filter_config(cfg, teleop):
        builder = DiagramBuilder()
        src = diagrams.AddMeasurementSource(builder, cfg)
        ports = diagrams.AddMocapPipeline(builder, cfg, BodyDimensions.paper_participant(), src, teleop=teleop)
        return ports.systems["filter"].filter.config

    cfg = PipelineConfig(source="sim", motion="I", cycles=1).validate()
    gated = filter_config(cfg, True)
    assert (gated.gate_sigma, gated.gate_speed_m_s) == (5.0, 6.0)
    plain = filter_config(cfg, False)
    assert plain.gate_sigma is None and plain.gate_speed_m_s is None


def test_filter_settings_from_the_command_line(tmp_path):
    """``--filter-settings``: the teleop preset (what the teleop diagram's filter runs with), fields inline or in
    JSON, the two together (a later field wins), 0 for off, and errors that name the option and the field."""
    assert parse_filter_settings("teleop") == TELEOP_FILTER_SETTINGS == {
        "gate_sigma": 5.0, "gate_whole_landmark": True, "gate_speed_m_s": 6.0, "max_predict_s": 0.3}
    assert parse_filter_settings("teleop,gate_speed_m_s=0,gate_max_rejects=3") == {
        "gate_sigma": 5.0, "gate_whole_landmark": True, "gate_speed_m_s": None, "max_predict_s": 0.3,
        "gate_max_rejects": 3}
    assert parse_filter_settings("accel_psd=3,max_predict_s=inf") == {"accel_psd": 3.0, "max_predict_s": float("inf")}
    path = tmp_path / "filters.json"
    path.write_text('{"gate_sigma": 4, "gate_whole_landmark": false}')
    assert parse_filter_settings(str(path)) == {"gate_sigma": 4, "gate_whole_landmark": False}
    for text, match in (("gate=5", "unknown field.*gate.*gate_sigma"), ("gate_sigma=-1", "gate_sigma"),
                        ("gate_sigma=five", "gate_sigma='five' is not a number"), ("", "empty"),
                        ("gate_speed_m_s=inf", "gate_speed_m_s")):
        with pytest.raises(UserError, match="--filter-settings.*" + match):
            parse_filter_settings(text)


def test_camera_placement_from_the_command_line(tmp_path):
    """``--camera``: the default camera however spelt (one render-cache key), fields inline or in JSON with the
    rest the default's, words for the tables, and errors that name the option and the field."""
    assert DEFAULT_CAMERA == {"distance_m": CameraConfig().distance_m, "height_m": CameraConfig().height_m,
                              "lateral_m": 0.0, "aim_height_m": None}
    for text in ("default", " Default ", "distance_m=2", "lateral_m=0,height_m=0.45", "aim_height_m=0.45"):
        assert parse_camera(text) == "default", text
    assert parse_camera("distance_m=3") == {"distance_m": 3.0, "height_m": 0.45, "lateral_m": 0.0,
                                            "aim_height_m": None}
    high = parse_camera("distance_m=2.5,height_m=1.1,aim_height_m=0.45")
    assert high == {"distance_m": 2.5, "height_m": 1.1, "lateral_m": 0.0, "aim_height_m": 0.45}
    path = tmp_path / "camera.json"
    path.write_text('{"lateral_m": -1, "distance_m": 2.2}')
    side = parse_camera(str(path))
    assert side == {"distance_m": 2.2, "height_m": 0.45, "lateral_m": -1.0, "aim_height_m": None}
    assert describe_camera("default") == "default camera"
    assert describe_camera(high) == "camera 2.5 m in front, 1.1 m above the pelvis, aimed 0.45 m above the pelvis"
    assert describe_camera(side) == "camera 2.2 m in front, 0.45 m above the pelvis, 1 m to the right, level"
    for text, match in (("dist=3", "unknown field.*dist.*distance_m"), ("distance_m=0.2", "more than 0.3 m"),
                        ("height_m=high", "height_m='high' is not a number"), ("lateral_m=nan", "lateral_m"),
                        ("", "empty")):
        with pytest.raises(UserError, match="--camera.*" + match):
            parse_camera(text)
    path.write_text('{"distance_m": "far"}')
    with pytest.raises(UserError, match="--camera: distance_m must be a finite number"):
        parse_camera(str(path))
    # The diagrams' camera takes the same fields (YAML keys), checked.
    yaml_path = tmp_path / "placed.yaml"
    yaml_path.write_text("camera:\n  distance_m: 2.5\n  lateral_m: -0.5\n  aim_height_m: 0.45\n")
    cam = load_config(yaml_path).camera
    assert (cam.distance_m, cam.height_m, cam.lateral_m, cam.aim_height_m) == (2.5, 0.45, -0.5, 0.45)
    yaml_path.write_text("camera:\n  distance_m: 3.0\n")
    assert load_config(yaml_path).camera.aim_height_m is None  # (level, at the camera's height)
    yaml_path.write_text("camera:\n  distance_m: 0.2\n")
    with pytest.raises(UserError, match="config.camera: distance_m .more than 0.3 m."):
        load_config(yaml_path)


def test_depth_lookup_settings_load_validate_and_reach_the_extractor(tmp_path):
    """``depth_rule`` and ``depth_window_px``: YAML keys, checked, and what the diagram's extractor runs with."""
    from pydrake.systems.framework import DiagramBuilder

    from akc_drake import diagrams
    from akc_drake.core.skeleton import BodyDimensions

    assert (PipelineConfig().depth_rule, PipelineConfig().depth_window_px) == ("nearest", 0)
    path = tmp_path / "run.yaml"
    path.write_text("depth_rule: median\ndepth_window_px: 5\n")
    cfg = load_config(str(path))
    assert (cfg.depth_rule, cfg.depth_window_px) == ("median", 5)
    with pytest.raises(UserError, match="config.depth_rule must be one of median, nearest"):
        PipelineConfig(depth_rule="mean").validate()
    for bad in (4, -3, 2.0):
        with pytest.raises(UserError, match="config.depth_window_px must be 0 .* or a positive odd integer"):
            PipelineConfig(depth_window_px=bad).validate()
    builder = DiagramBuilder()
    cfg = PipelineConfig(source="sim", motion="I", cycles=1, depth_rule="median", depth_window_px=7).validate()
    src = diagrams.AddMeasurementSource(builder, cfg)
    diagrams.AddMocapPipeline(builder, cfg, BodyDimensions.paper_participant(), src)
    ext = src["systems"]["extractor"]
    assert (ext.depth_rule, ext.window) == ("median", 7)
    # 0: the window scales with the focal length (15 pixels at 640x480, 3 at 160x120).
    for camera, window in ((CameraConfig(), 15), (CameraConfig(width=160, height=120), 3)):
        cfg = PipelineConfig(source="sim", motion="I", cycles=1, camera=camera).validate()
        src = diagrams.AddMeasurementSource(DiagramBuilder(), cfg)
        assert (src["systems"]["extractor"].depth_rule, src["systems"]["extractor"].window) == ("nearest", window)


def test_depth_noise_from_the_command_line(tmp_path):
    """``--depth-noise``: the default model however spelt (one render-cache key), the changed fields only, inline or
    in JSON, the model they make, words for the tables, and errors that name the option and the field."""
    for text in ("default", " DEFAULT ", "sigma_disparity_px=0.08", "correlation_px=0,edge_width_px=1"):
        assert parse_depth_noise(text) == "default", text
    real = parse_depth_noise("sigma_disparity_px=0.16, correlation_px=4")
    assert real == {"sigma_disparity_px": 0.16, "correlation_px": 4.0}
    model = depth_noise_model(real)
    assert (model.sigma_disparity_px, model.correlation_px, model.baseline_m) == (0.16, 4.0, 0.05)
    assert depth_noise_model("default") == depth_noise_model(None) == CameraConfig().depth_noise()
    path = tmp_path / "noise.json"
    path.write_text('{"edge_width_px": 3, "baseline_m": 0.095}')
    assert parse_depth_noise(str(path)) == {"edge_width_px": 3, "baseline_m": 0.095}
    assert describe_depth_noise("default") == "default depth noise"
    assert describe_depth_noise(real) == "depth noise sigma_disparity_px=0.16, correlation_px=4"
    for text, match in (("sigma=0.2", "unknown field.*sigma.*sigma_disparity_px"),
                        ("correlation_px=-2", "correlation_px must be a number >= 0"),
                        ("edge_width_px=1.5", "edge_width_px='1.5' is not a number"),
                        ("baseline_m=wide", "baseline_m='wide' is not a number"), ("", "empty")):
        with pytest.raises(UserError, match="--depth-noise.*" + match):
            parse_depth_noise(text)
    with pytest.raises(ValueError, match="unknown field.*sigma"):
        depth_noise_model({"sigma": 1.0})
    # The diagrams' camera carries the correlation too (a YAML key).
    assert CameraConfig(noise_correlation_px=3.0).depth_noise().correlation_px == 3.0
