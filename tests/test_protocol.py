import math

import pytest

from akc_drake.core.occlusion import PAPER_RULES
from akc_drake.errors import UserError
from akc_drake.evaluation.experiment import ExperimentConfig
from akc_drake.evaluation.methods import MethodOptions
from akc_drake.evaluation.protocol import check_protocol, method_options, paper_coik_config, render_kwargs


def test_paper_protocol_is_the_papers_pipeline():
    o = method_options("paper")
    assert o.kf_config.max_predict_s == math.inf and o.ekf_config.max_predict_s == math.inf
    assert o.ekf_kind == "per_joint"
    assert o.occlusion_rules == PAPER_RULES
    # No depth offset: a seen depth reads the surface, so AKC+ does not take it as read after an EKF.
    assert o.akc_plus_config == {"seen_depth_sigma_m": 0.0}
    assert method_options("ours").akc_plus_config is None
    c = paper_coik_config()
    assert not c.warm_start and c.iteration_limit == 10
    assert render_kwargs("paper") == {"surface_offset_m": 0.0, "window": 5, "depth_rule": "median"}


def test_ours_protocol_is_the_default_stages():
    o = method_options("ours")
    assert o.kf_config is None and o.ekf_kind == "coupled" and o.occlusion_rules is None
    assert render_kwargs("ours") == {}
    cfg = ExperimentConfig(protocol="ours")
    assert cfg.run_options() is cfg.options
    paper = ExperimentConfig(protocol="paper", cycles=1).run_options()
    assert paper.ekf_kind == "per_joint" and paper.visibility_threshold == 0.7
    # AKC+'s settings (--akc-plus) ride along under either protocol, over the protocol's own.
    tuned = MethodOptions(akc_plus_config={"gate_sigma": 2.5})
    run = ExperimentConfig(protocol="ours", cycles=1, options=tuned).run_options()
    assert run.akc_plus_config == {"gate_sigma": 2.5}
    run = ExperimentConfig(protocol="paper", cycles=1, options=tuned).run_options()
    assert run.akc_plus_config == {"gate_sigma": 2.5, "seen_depth_sigma_m": 0.0}
    mine = MethodOptions(akc_plus_config={"seen_depth_sigma_m": 0.02})
    assert ExperimentConfig(protocol="paper", cycles=1, options=mine).run_options().akc_plus_config == {
        "seen_depth_sigma_m": 0.02}
    # A bad setting fails when the experiment is configured, not later in each worker.
    with pytest.raises(ValueError, match="unknown AKC\\+ setting.*'gate'"):
        ExperimentConfig(cycles=1, options=MethodOptions(akc_plus_config={"gate": 2.5}))


def test_unknown_protocol():
    with pytest.raises(UserError, match="--protocol"):
        check_protocol("nope")
    with pytest.raises(ValueError, match="protocol"):
        ExperimentConfig(protocol="nope")
