"""Stage S5: the control frames of eq. (17) mapped to the robot's end-effector targets, as a Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import BasicVector, LeafSystem

from akc_drake.core.frames import (
    DEFAULT_MAX_LANDMARK_SPEED,
    SPEED_GATED_LANDMARKS,
    RobotMapping,
    default_home_pose,
    plausible_step,
    robot_targets,
    smooth_torso,
    torso_of,
)
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, SIDES
from akc_drake.systems import timing

POSE_SIZE = 3 * NUM_LANDMARKS


def _as_rigid_transform(X, name: str) -> RigidTransform:
    if isinstance(X, RigidTransform):
        return RigidTransform(X)
    a = np.asarray(X, dtype=float)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a RigidTransform or a finite 4x4 transform, got shape {a.shape}")
    R = a[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) <= 0.0:
        raise ValueError(f"{name}: the rotation part is not a proper rotation matrix: {R.tolist()}")
    if not np.allclose(a[3], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(
            f"{name}: the last row of a homogeneous transform must be [0, 0, 0, 1], got {a[3].tolist()}"
        )
    return RigidTransform(RotationMatrix(R), a[:3, 3])


def _to_rigid_transform(X: np.ndarray) -> RigidTransform:
    # The rotation is built from normalised cross products (orthonormal to ~1e-15); re-orthonormalise only if
    # Drake's check ever rejects it.
    try:
        R = RotationMatrix(X[:3, :3])
    except (RuntimeError, ValueError):
        R = RotationMatrix.ProjectToRotationMatrix(X[:3, :3])
    return RigidTransform(R, X[:3, 3])


class FrameMapper(LeafSystem):
    """Builds the torso and wrist frames of eq. (17) from the corrected pose and maps the wrists to the
    robot's end-effector targets ``X_TE`` (robot torso frame T), once per camera frame.

    .. pydrake_system::

        name: FrameMapper
        input_ports:
        - landmarks_C
        output_ports:
        - X_TE_desired_left
        - X_TE_desired_right
        - tracking_lost

    ``landmarks_C`` is the ``(12, 3)`` camera-frame pose flattened row-major (36). ``X_TE_desired_*`` are
    ``RigidTransform`` values (see :mod:`akc_drake.core.frames` for the frame conventions). ``tracking_lost``
    is ``[left, right]``, 1.0 when that side's frame could not be built from the latest frame (missing or
    degenerate landmarks) and the last valid target is held; before the first valid frame the target is the
    home pose and ``tracking_lost`` is 1.0.

    Speed gate: when a landmark the side's target is built from (its wrist, index, pinky and the hips, see
    :data:`~akc_drake.core.frames.SPEED_GATED_LANDMARKS`) would have moved faster than ``max_landmark_speed``
    (camera frame, m/s) since that side's last accepted frame, the frame is a fault (a detector jump, a
    swapped side, a bad depth that got through), not a motion: it is treated as lost for that side (target
    held, ``tracking_lost`` 1.0). The allowance grows with the time since the last accepted frame, so a
    person who really moved during a tracking loss is accepted as soon as it is plausible again; the robot
    then goes there at its own speed limits.

    State: abstract groups holding the last valid ``X_TE`` per side, a discrete group ``tracking_lost`` (2)
    and a discrete group with each side's last accepted gated landmarks and time (2 x 16: 5 x 3 positions
    then t; NaN before the first), set by a periodic unrestricted update at the camera period, offset by
    ``timing.stage_offset("mapper")``; outputs are the state.

    Args:
        mapping: operator-to-robot mapping (default :meth:`RobotMapping.default`).
        X_TE_home_left, X_TE_home_right: home targets (``RigidTransform`` or 4x4), normally the robot's
            nominal end-effector poses in T; default :func:`akc_drake.core.frames.default_home_pose` (the
            operator's rest posture mapped through ``mapping``).
        period_s: camera period, seconds.
        stage_offset_s: per-stage offset (see :mod:`akc_drake.systems.timing`).
        max_landmark_speed: the speed gate, m/s (default
            :data:`~akc_drake.core.frames.DEFAULT_MAX_LANDMARK_SPEED`); None turns it off.
        torso_tau_s: time constant of the torso-frame low-pass (:func:`~akc_drake.core.frames.smooth_torso`);
            0 (the default here) uses each frame's torso as it is; the teleop diagram uses 0.5 s.
    """

    def __init__(
        self,
        mapping: RobotMapping | None = None,
        *,
        X_TE_home_left=None,
        X_TE_home_right=None,
        period_s: float = 1.0 / timing.DEFAULT_CAMERA_RATE_HZ,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
        max_landmark_speed: float | None = DEFAULT_MAX_LANDMARK_SPEED,
        torso_tau_s: float = 0.0,
    ):
        super().__init__()
        if not (isinstance(torso_tau_s, (int, float)) and np.isfinite(torso_tau_s) and torso_tau_s >= 0.0):
            raise ValueError(f"torso_tau_s must be a time constant >= 0 s, got {torso_tau_s!r}")
        self._torso_tau = float(torso_tau_s)
        self._period = float(period_s)
        if not (np.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
        v = max_landmark_speed
        if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0.0):
            raise ValueError(f"max_landmark_speed must be > 0 m/s or None, got {v!r}")
        self._max_speed = None if v is None else float(v)
        self._gated = {side: [INDEX[n] for n in SPEED_GATED_LANDMARKS[side]] for side in SIDES}
        self._n_gated = len(self._gated["left"])
        self._mapping = mapping if mapping is not None else RobotMapping.default()
        homes = {"left": X_TE_home_left, "right": X_TE_home_right}
        self._home = {}
        for side in SIDES:
            X = homes[side]
            if X is None:
                X = default_home_pose(side, self._mapping)
            self._home[side] = _as_rigid_transform(X, f"X_TE_home_{side}")

        self._input = self.DeclareVectorInputPort("landmarks_C", BasicVector(POSE_SIZE))
        self._X_state = {
            side: self.DeclareAbstractState(AbstractValue.Make(RigidTransform(self._home[side])))
            for side in SIDES
        }
        self._lost = self.DeclareDiscreteState(np.ones(2))
        self._accepted = self.DeclareDiscreteState(np.full(2 * (3 * self._n_gated + 1), np.nan))
        # The smoothed torso frame: R (9, row-major), origin (3), time of the last update (NaN: none yet).
        self._torso = self.DeclareDiscreteState(np.full(13, np.nan))
        for side in SIDES:
            self.DeclareStateOutputPort(f"X_TE_desired_{side}", self._X_state[side])
        self.DeclareStateOutputPort("tracking_lost", self._lost)
        self.DeclarePeriodicUnrestrictedUpdateEvent(
            period_sec=period_s,
            offset_sec=timing.stage_offset("mapper", stage_offset_s),
            update=self._update,
        )

    @property
    def mapping(self) -> RobotMapping:
        return self._mapping

    def home_pose(self, side: str) -> RigidTransform:
        """The home target of ``side``."""
        return RigidTransform(self._home[side])

    def _smoothed_torso(self, context, state, pose):
        """The low-passed torso frame (see :func:`~akc_drake.core.frames.smooth_torso`), kept in state."""
        v = np.array(context.get_discrete_state(self._torso).get_value(), dtype=float)
        previous = None if not np.isfinite(v[12]) else (v[:9].reshape(3, 3), v[9:12])
        t = context.get_time()
        dt = self._period if previous is None else t - v[12]
        torso = smooth_torso(previous, torso_of(pose), dt, self._torso_tau)
        if torso is not None:
            R, o = torso
            state.get_mutable_discrete_state(self._torso).SetFromVector(np.concatenate([R.ravel(), o, [t]]))
        return torso

    def _update(self, context, state) -> None:
        pose = self._input.Eval(context).reshape(NUM_LANDMARKS, 3)
        torso = None
        if self._torso_tau > 0.0:
            torso = self._smoothed_torso(context, state, pose)
        targets = robot_targets(pose, self._mapping, torso)
        lost = np.array(context.get_discrete_state(self._lost).get_value(), dtype=float)
        n = 3 * self._n_gated
        accepted = np.array(context.get_discrete_state(self._accepted).get_value(), dtype=float)
        accepted = accepted.reshape(2, n + 1)
        t = context.get_time()
        for k, (side, X) in enumerate(zip(SIDES, targets, strict=True)):
            if X is None:
                # Degenerate or missing landmarks: hold the last valid target and raise tracking_lost.
                lost[k] = 1.0
                continue
            points = pose[self._gated[side]]
            last = accepted[k]
            if self._max_speed is not None and np.isfinite(last[n]):
                if not plausible_step(last[:n].reshape(-1, 3), points, t - last[n], self._max_speed):
                    lost[k] = 1.0  # a jump no person can make: a fault; hold (see the class docstring)
                    continue
            state.get_mutable_abstract_state(self._X_state[side]).set_value(_to_rigid_transform(X))
            lost[k] = 0.0
            accepted[k, :n] = points.reshape(-1)
            accepted[k, n] = t
        state.get_mutable_discrete_state(self._lost).SetFromVector(lost)
        state.get_mutable_discrete_state(self._accepted).SetFromVector(accepted.reshape(-1))
