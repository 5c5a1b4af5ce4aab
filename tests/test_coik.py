import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.solvers import SolutionResult
from scipy.optimize import minimize

from akc_drake.core import coik
from akc_drake.core.coik import COIKConfig, COIKOptionError, COIKSolver, available_solvers
from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.errors import UserError

DIMS = BodyDimensions.paper_participant()
SOLVERS = available_solvers()
ARM = ["left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist"]


def _unit(v):
    return v / np.linalg.norm(v)


def true_pose(t: float, dims: BodyDimensions = DIMS) -> np.ndarray:
    """A (12, 3) camera-frame pose whose arms have exactly the calibrated lengths and elbows > 40 deg."""
    pose = np.zeros((12, 3))
    centre = np.array([0.02 * math.sin(0.7 * t), -0.30, 2.0 + 0.03 * math.sin(0.5 * t)])
    yaw = 0.1 * math.sin(0.4 * t)
    across = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        a = 0.5 + 0.45 * math.sin(2 * math.pi * t / 6.0 + (0.0 if sign > 0 else 1.0))
        s = centre + sign * 0.5 * dims.SW * across
        u = _unit(np.array([sign * 0.3 * math.sin(a), math.cos(a), -math.sin(a)]))
        e = s + dims.upper(side) * u
        f = _unit(np.array([sign * 0.15, -0.4 * math.sin(a), -1.0]))
        w = e + dims.lower(side) * f
        pose[INDEX[f"{side}_shoulder"]], pose[INDEX[f"{side}_elbow"]], pose[INDEX[f"{side}_wrist"]] = s, e, w
        pose[INDEX[f"{side}_index"]] = w + np.array([-sign * 0.02, 0.0, -0.08])
        pose[INDEX[f"{side}_pinky"]] = w + np.array([sign * 0.02, 0.0, -0.07])
        pose[INDEX[f"{side}_hip"]] = centre + np.array([sign * 0.1, 0.5, 0.0])
    return pose


def noisy_sequence(n: int, *, seed: int = 0, occlude: bool = True, sigma: float = 0.01) -> np.ndarray:
    """Noisy filtered poses; in occluded stretches the left shoulder/elbow depth is the wrist's."""
    rng = np.random.default_rng(seed)
    poses = np.stack([true_pose(0.1 * k) for k in range(n)])
    poses = poses + rng.normal(0.0, sigma, poses.shape)
    if occlude:
        for k in range(n):
            if (k // 10) % 2 == 1:
                wz = poses[k, INDEX["left_wrist"], 2]
                poses[k, INDEX["left_shoulder"], 2] = wz + 0.02
                poses[k, INDEX["left_elbow"], 2] = wz + 0.01
    return poses


def segment_errors(pose: np.ndarray, dims: BodyDimensions = DIMS) -> np.ndarray:
    def d(a, b):
        return np.linalg.norm(pose[INDEX[a]] - pose[INDEX[b]])

    return np.abs(
        np.array(
            [
                d("left_shoulder", "left_elbow") - dims.LUA,
                d("left_elbow", "left_wrist") - dims.LLA,
                d("right_shoulder", "right_elbow") - dims.RUA,
                d("right_elbow", "right_wrist") - dims.RLA,
                d("left_shoulder", "right_shoulder") - dims.SW,
            ]
        )
    )


def elbow_angles_deg(pose: np.ndarray) -> np.ndarray:
    out = []
    for side in ("left", "right"):
        s, e, w = (pose[INDEX[f"{side}_{j}"]] for j in ("shoulder", "elbow", "wrist"))
        c = np.dot(s - e, w - e) / (np.linalg.norm(s - e) * np.linalg.norm(w - e))
        out.append(math.degrees(math.acos(np.clip(c, -1.0, 1.0))))
    return np.array(out)


def coik_cost(p, p_hat, p_prev, lam):
    return float(np.sum((p - p_hat) ** 2) + lam * np.sum((p - p_prev) ** 2))


def test_all_three_solvers_are_available_here():
    assert set(SOLVERS) == {"snopt", "ipopt", "nlopt"}


@pytest.mark.parametrize("solver", SOLVERS)
def test_feasible_frames_meet_equalities_and_angle_bound(solver):
    s = COIKSolver(DIMS, COIKConfig(solver=solver))
    poses = noisy_sequence(30)
    successes = 0
    for frame in poses:
        r = s.solve(frame)
        assert r.solver == solver and np.all(np.isfinite(r.pose))
        assert r.solve_time_s > 0.0
        if r.status == "success":
            successes += 1
            assert segment_errors(r.pose).max() < 1e-6
            assert r.max_length_error_m == pytest.approx(segment_errors(r.pose).max(), abs=1e-12)
            assert np.all(elbow_angles_deg(r.pose) >= 40.0 - 1e-4)
    assert successes >= 28


@pytest.mark.parametrize("solver", SOLVERS)
def test_angle_bound_is_enforced_when_the_reference_violates_it(solver):
    # A reference with exact lengths but a 20 deg elbow: the optimum sits on the 40 deg bound.
    pose = true_pose(0.0)
    s, e = pose[INDEX["left_shoulder"]], pose[INDEX["left_elbow"]]
    back = _unit(s - e)
    side = _unit(np.cross(back, np.array([1.0, 0.0, 0.0])))
    f = math.cos(math.radians(20)) * back + math.sin(math.radians(20)) * side
    pose[INDEX["left_wrist"]] = e + DIMS.LLA * f
    assert elbow_angles_deg(pose)[0] == pytest.approx(20.0, abs=1e-9)
    r = COIKSolver(DIMS, COIKConfig(solver=solver)).solve(pose)
    assert r.status == "success"
    assert elbow_angles_deg(r.pose)[0] == pytest.approx(40.0, abs=1e-3)
    assert segment_errors(r.pose).max() < 1e-6


def test_feasible_reference_is_a_fixed_point():
    pose = true_pose(1.3)
    r = COIKSolver(DIMS).solve(pose)
    assert r.status == "success"
    np.testing.assert_allclose(r.pose, pose, atol=1e-7)


def test_optimum_matches_an_independent_scipy_formulation():
    # Same program written independently (lengths as norms, angle with acos) and solved by scipy's SLSQP.
    poses = noisy_sequence(3, seed=4, occlude=False)
    lam = 0.5
    s = COIKSolver(DIMS, COIKConfig(lam=lam))
    s.solve(poses[0])
    p_prev = s.previous_solution
    r = s.solve(poses[1])
    p_hat = poses[1][[INDEX[n] for n in ARM]].reshape(18)

    def pt(p, k):
        return p[3 * k : 3 * k + 3]

    cons = []
    for k0, (lu, lf) in ((0, (DIMS.LUA, DIMS.LLA)), (3, (DIMS.RUA, DIMS.RLA))):
        cons.append(
            {"type": "eq", "fun": lambda p, k0=k0, lf=lf: np.linalg.norm(pt(p, k0 + 1) - pt(p, k0 + 2)) - lf}
        )
        cons.append(
            {"type": "eq", "fun": lambda p, k0=k0, lu=lu: np.linalg.norm(pt(p, k0) - pt(p, k0 + 1)) - lu}
        )

        def angle(p, k0=k0):
            a, b = pt(p, k0) - pt(p, k0 + 1), pt(p, k0 + 2) - pt(p, k0 + 1)
            return (
                math.degrees(math.acos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1)))
                - 40.0
            )

        cons.append({"type": "ineq", "fun": angle})
    cons.append({"type": "eq", "fun": lambda p: np.linalg.norm(pt(p, 0) - pt(p, 3)) - DIMS.SW})
    ref = minimize(
        coik_cost,
        p_prev,
        args=(p_hat, p_prev, lam),
        method="SLSQP",
        constraints=cons,
        options={"ftol": 1e-14},
    )
    assert ref.success
    ours = r.pose[[INDEX[n] for n in ARM]].reshape(18)
    np.testing.assert_allclose(ours, ref.x, atol=1e-5)
    assert coik_cost(ours, p_hat, p_prev, lam) <= coik_cost(ref.x, p_hat, p_prev, lam) + 1e-9


@pytest.mark.parametrize("solver, limit", [("snopt", 1), ("ipopt", 1), ("nlopt", 2)])
def test_tiny_iteration_limit_reports_iteration_limit_and_outputs_last_iterate(solver, limit):
    if solver not in SOLVERS:
        pytest.skip(f"{solver} not available")
    pose = true_pose(0.0)
    # A reference far from feasible: arms stretched 30 %.
    for side in ("left", "right"):
        s = pose[INDEX[f"{side}_shoulder"]]
        for j in ("elbow", "wrist"):
            pose[INDEX[f"{side}_{j}"]] = s + 1.3 * (pose[INDEX[f"{side}_{j}"]] - s)
    r = COIKSolver(DIMS, COIKConfig(solver=solver, iteration_limit=limit)).solve(pose)
    assert r.status == "iteration_limit" and r.status_code == 1
    assert np.all(np.isfinite(r.pose))
    # The last iterate moved away from the reference but does not yet meet the lengths
    # (paper Table VII, "COIK I").
    assert not np.allclose(r.pose, pose)
    assert r.max_length_error_m > 1e-4


def test_warm_start_changes_nothing_in_the_optimum():
    poses = noisy_sequence(40, seed=1, occlude=False)
    warm = COIKSolver(DIMS, COIKConfig(warm_start=True))
    cold = COIKSolver(DIMS, COIKConfig(warm_start=False))
    for frame in poses:
        rw, rc = warm.solve(frame), cold.solve(frame)
        assert rw.status == rc.status == "success"
        np.testing.assert_allclose(rw.pose, rc.pose, atol=1e-5)
        # (no assertion on the solve times: they depend on the machine's load; `akc-drake bench` measures them)
        assert math.isfinite(rw.solve_time_s) and rw.solve_time_s >= 0.0


def test_missing_coordinates_use_the_previous_solution_and_nan_only_frames_hold():
    s = COIKSolver(DIMS)
    poses = noisy_sequence(4, seed=2, occlude=False)
    first = poses[0].copy()
    first[INDEX["left_elbow"], 2] = np.nan
    r0 = s.solve(first)  # no previous solution: the missing depth is borrowed from the same arm, then solved
    assert r0.status == "success" and np.all(np.isfinite(r0.pose[[INDEX[n] for n in ARM]]))
    np.testing.assert_array_equal(r0.pose[INDEX["left_hip"]], first[INDEX["left_hip"]])
    s.reset()
    no_xy = poses[0].copy()
    no_xy[INDEX["left_elbow"]] = np.nan  # x, y missing too: nothing to fill from -> held, arms NaN
    r0 = s.solve(no_xy)
    assert r0.status == "held" and r0.status_code == 4 and r0.solve_time_s == 0.0
    assert np.all(np.isnan(r0.pose[[INDEX[n] for n in ARM]]))

    r1 = s.solve(poses[1])
    assert r1.status == "success"
    prev = s.previous_solution.copy()

    partial = poses[2].copy()
    partial[INDEX["left_elbow"]] = np.nan
    partial[INDEX["right_shoulder"], 2] = np.inf
    r2 = s.solve(partial)
    assert r2.status == "success" and np.all(np.isfinite(r2.pose))
    assert segment_errors(r2.pose).max() < 1e-6
    # The missing elbow is pulled only toward the previous solution: it stays close to it.
    assert np.linalg.norm(r2.pose[INDEX["left_elbow"]] - prev[3:6]) < 0.03

    blank = poses[3].copy()
    blank[[INDEX[n] for n in ARM]] = np.nan
    r3 = s.solve(blank)
    assert r3.status == "held"
    np.testing.assert_array_equal(r3.pose[[INDEX[n] for n in ARM]], r2.pose[[INDEX[n] for n in ARM]])


def test_non_arm_landmarks_pass_through_and_shape_is_checked():
    pose = noisy_sequence(1, seed=3)[0]
    r = COIKSolver(DIMS).solve(pose)
    others = [i for i in range(12) if i not in [INDEX[n] for n in ARM]]
    np.testing.assert_array_equal(r.pose[others], pose[others])
    with pytest.raises(ValueError, match=r"pose must have shape \(12, 3\)"):
        COIKSolver(DIMS).solve(np.zeros((11, 3)))


def test_state_vector_round_trip_reproduces_the_sequence():
    poses = noisy_sequence(6, seed=5)
    a = COIKSolver(DIMS)
    for frame in poses[:3]:
        a.solve(frame)
    b = COIKSolver(DIMS)
    b.set_state_vector(a.get_state_vector())
    for frame in poses[3:]:
        np.testing.assert_array_equal(a.solve(frame).pose, b.solve(frame).pose)
    a.reset()
    assert a.previous_solution is None and a.get_state_vector()[-1] == 0.0
    with pytest.raises(ValueError, match="state vector"):
        a.set_state_vector(np.zeros(5))


def test_config_validation_names_the_field():
    with pytest.raises(COIKOptionError, match="solver.*'cplex'"):
        COIKConfig(solver="cplex")
    with pytest.raises(ValueError, match="lam"):
        COIKConfig(lam=-0.1)
    with pytest.raises(ValueError, match="iteration_limit"):
        COIKConfig(iteration_limit=0)
    with pytest.raises(ValueError, match="elbow_min_deg"):
        COIKConfig(elbow_min_deg=100.0, elbow_max_deg=90.0)
    with pytest.raises(ValueError, match="constraint_tol"):
        COIKConfig(constraint_tol=0.0)
    assert issubclass(COIKOptionError, UserError) and issubclass(COIKOptionError, ValueError)


def test_unavailable_solver_gives_a_clear_error(monkeypatch):
    class Unavailable:
        def available(self):
            return False

        def enabled(self):
            return True

    monkeypatch.setitem(coik._SOLVER_CLASSES, "ipopt", Unavailable)
    assert "ipopt" not in available_solvers()
    with pytest.raises(COIKOptionError, match="'ipopt' is not available.*available: snopt"):
        COIKSolver(DIMS, COIKConfig(solver="ipopt"))


def test_status_mapping():
    f = coik.status_from_solution_result
    assert f(SolutionResult.kSolutionFound) == "success"
    assert f(SolutionResult.kIterationLimit) == "iteration_limit"
    assert f(SolutionResult.kInfeasibleConstraints) == "infeasible"
    assert f(SolutionResult.kInfeasibleOrUnbounded) == "infeasible"
    assert f(SolutionResult.kSolverSpecificError) == "failed"
    assert [coik.STATUS_CODES[s] for s in coik.STATUSES] == [0, 1, 2, 3, 4]


def _right_arm_at(pose: np.ndarray, angle_deg: float) -> np.ndarray:
    pose = pose.copy()
    s, e = pose[INDEX["right_shoulder"]], pose[INDEX["right_elbow"]]
    back = _unit(s - e)
    side = _unit(np.cross(back, np.array([1.0, 0.0, 0.0])))
    a = math.radians(angle_deg)
    pose[INDEX["right_wrist"]] = e + DIMS.RLA * (math.cos(a) * back + math.sin(a) * side)
    return pose


@pytest.mark.parametrize("solver", SOLVERS)
def test_elbow_upper_bound_when_configured(solver):
    # With elbow_max_deg = 150 an almost straight reference arm (179 deg) must bend to 150 deg.
    pose = _right_arm_at(true_pose(0.0), 179.0)
    assert elbow_angles_deg(pose)[1] == pytest.approx(179.0, abs=1e-9)
    r = COIKSolver(DIMS, COIKConfig(elbow_max_deg=150.0, solver=solver)).solve(pose)
    assert r.status == "success"
    assert elbow_angles_deg(r.pose)[1] == pytest.approx(150.0, abs=1e-3)
    assert segment_errors(r.pose).max() < 1e-6


def test_exactly_straight_start_against_an_upper_angle_bound_is_reported_infeasible():
    # At an exactly straight arm the gradients of the length and angle constraints are parallel, so SNOPT's
    # linearisation cannot reach theta <= 150 deg and it stops as locally infeasible: COIK reports it and
    # outputs the solver's last iterate (finite), as the paper describes for failed solves.
    pose = _right_arm_at(true_pose(0.0), 180.0)
    r = COIKSolver(DIMS, COIKConfig(elbow_max_deg=150.0, solver="snopt")).solve(pose)
    assert r.status == "infeasible" and r.status_code == 2
    assert np.all(np.isfinite(r.pose))


def test_solve_sequence_reports_a_time_per_frame():
    poses = noisy_sequence(30, seed=6)
    traj, results = COIKSolver(DIMS).solve_sequence(poses)
    assert traj.shape == (30, 12, 3)
    times = np.array([r.solve_time_s for r in results])
    # Structure only: one finite, non-negative time per frame (speed is `akc-drake bench`'s business).
    assert times.shape == (30,) and np.all(np.isfinite(times) & (times >= 0.0))


@settings(max_examples=25, deadline=None)
@given(
    t=st.floats(0.0, 12.0),
    noise=st.floats(0.0, 0.05),
    seed=st.integers(0, 2**31 - 1),
    lam=st.floats(0.0, 2.0),
)
def test_property_success_implies_constraints(t, noise, seed, lam):
    rng = np.random.default_rng(seed)
    pose = true_pose(t) + rng.normal(0.0, noise, (12, 3))
    r = COIKSolver(DIMS, COIKConfig(lam=lam)).solve(pose)
    assert np.all(np.isfinite(r.pose))
    if r.status == "success":
        assert segment_errors(r.pose).max() < 1e-6
        assert np.all(elbow_angles_deg(r.pose) >= 40.0 - 1e-3)


def test_first_frame_with_a_hidden_shoulder_depth_is_solved_not_held():
    """A shoulder whose depth is missing from the very first frame (Motion II) still gets a solution."""
    from akc_drake.core.coik import COIKSolver
    from akc_drake.core.skeleton import INDEX, BodyDimensions

    dims = BodyDimensions.paper_participant()
    pose = np.full((12, 3), np.nan)
    for side in ("left", "right"):
        x = 0.166 if side == "left" else -0.166
        pose[INDEX[f"{side}_shoulder"]] = [x, -0.3, np.nan]
        pose[INDEX[f"{side}_elbow"]] = [x, -0.3, 2.0 - dims.upper(side)]
        lf = dims.lower(side)  # forearm raised 37 deg: a bent elbow, well inside the angle bound
        pose[INDEX[f"{side}_wrist"]] = [x, -0.3 - 0.6 * lf, 2.0 - dims.upper(side) - 0.8 * lf]
    res = COIKSolver(dims).solve(pose)
    assert res.status == "success"
    sol = res.pose
    for side in ("left", "right"):
        s, e = sol[INDEX[f"{side}_shoulder"]], sol[INDEX[f"{side}_elbow"]]
        assert np.isfinite(s).all()
        assert abs(np.linalg.norm(s - e) - dims.upper(side)) < 1e-6
