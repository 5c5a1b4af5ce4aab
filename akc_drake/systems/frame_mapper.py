"""Stage S5: the control frames of eq. (17) mapped to the robot's end-effector targets, as a Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import BasicVector, LeafSystem

from akc_drake.core import smoothing
from akc_drake.core.control_frames import ControlFrameTracker
from akc_drake.core.frames import DEFAULT_MAX_LANDMARK_SPEED, RobotMapping, default_home_pose
from akc_drake.core.skeleton import NUM_LANDMARKS, SIDES
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
        - workspace_clipped

    ``landmarks_C`` is the ``(12, 3)`` camera-frame pose flattened row-major (36). The work is
    :class:`~akc_drake.core.control_frames.ControlFrameTracker`'s: torso (calibrated from the hips, or eq. 17),
    wrist frames kept off their mirror configuration, the speed gate, One Euro smoothing on SE(3), the
    workspace clip. ``X_TE_desired_*`` are ``RigidTransform`` values. ``tracking_lost`` is ``[left, right]``,
    1.0 when that side's target could not be built from the latest frame (missing or degenerate landmarks, or
    a jump the speed gate rejected) and the last target is held; before the first valid frame the target is the
    home pose. ``workspace_clipped`` is ``[left, right]``, 1.0 when the latest target was projected into the
    arm's workspace.

    State: abstract groups holding the last ``X_TE`` per side, discrete groups ``tracking_lost`` (2),
    ``workspace_clipped`` (2) and the tracker's state vector, set by a periodic unrestricted update at the
    camera period offset by ``timing.stage_offset("mapper")``; outputs are the state.

    Args:
        mapping: operator-to-robot mapping (default :meth:`RobotMapping.default`).
        X_TE_home_left, X_TE_home_right: home targets (``RigidTransform`` or 4x4), normally the robot's
            nominal end-effector poses in T; default :func:`akc_drake.core.frames.default_home_pose`.
        period_s: camera period, seconds.
        stage_offset_s: per-stage offset (see :mod:`akc_drake.systems.timing`).
        max_landmark_speed: the speed gate, m/s; None turns it off.
        torso_model: a calibrated :class:`~akc_drake.core.frames.TorsoModel` (None: eq. 17's torso).
        wrist_smoothing, torso_smoothing: :class:`~akc_drake.core.smoothing.SE3SmoothingParams` (None: off;
            defaults off here, the teleop diagram turns them on).
        workspace: per side a :class:`~akc_drake.core.frames.Workspace` to clip targets to (None: no clip).
        robust_wrist: rebuild the hand vector from its image part and keep the wrist frame off its mirror
            (:class:`~akc_drake.core.control_frames.ControlFrameTracker`); off here (eq. 17 as it is), on in the
            teleop diagram.
        torso_hold: :class:`~akc_drake.core.smoothing.HoldParams`: the torso held still while the operator stands
            (None: off; the teleop diagram uses :data:`~akc_drake.core.smoothing.TORSO_HOLD`).
        hand_knuckles_input: declare an input port ``hand_knuckles`` (6: left, right), MediaPipe Hands' knuckle
            vectors in normalised image units
            (:func:`~akc_drake.core.control_frames.hands_knuckle_vector`, NaN where no hand), used in place of the
            pose's two hand points when connected.
        hand_knuckles_replay: ``(frames, 2, 3)`` recorded knuckle vectors replayed one row per update (the
            mapper's k-th update takes row k, as :class:`~akc_drake.systems.measurement_replay.MeasurementReplay`
            emits frame k), used when the port is absent or unconnected.
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
        torso_model=None,
        wrist_smoothing: smoothing.SE3SmoothingParams | None = None,
        torso_smoothing: smoothing.SE3SmoothingParams | None = None,
        workspace: dict | None = None,
        robust_wrist: bool = False,
        torso_hold: smoothing.HoldParams | None = None,
        hand_knuckles_input: bool = False,
        hand_knuckles_replay=None,
    ):
        super().__init__()
        if not (np.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
        v = max_landmark_speed
        if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0.0):
            raise ValueError(f"max_landmark_speed must be > 0 m/s or None, got {v!r}")
        self._mapping = mapping if mapping is not None else RobotMapping.default()
        self._tracker = ControlFrameTracker(
            self._mapping,
            torso_model=torso_model,
            wrist_smoothing=wrist_smoothing,
            torso_smoothing=torso_smoothing,
            workspace=workspace,
            max_landmark_speed=None if v is None else float(v),
            robust_wrist=robust_wrist,
            torso_hold=torso_hold,
        )
        homes = {"left": X_TE_home_left, "right": X_TE_home_right}
        self._home = {}
        for side in SIDES:
            X = homes[side] if homes[side] is not None else default_home_pose(side, self._mapping)
            self._home[side] = _as_rigid_transform(X, f"X_TE_home_{side}")

        self._input = self.DeclareVectorInputPort("landmarks_C", BasicVector(POSE_SIZE))
        self._hands = self.DeclareVectorInputPort("hand_knuckles", BasicVector(6)) if hand_knuckles_input else None
        self._replay = (None if hand_knuckles_replay is None
                        else np.asarray(hand_knuckles_replay, float).reshape(-1, 2, 3))
        self._count = self.DeclareDiscreteState(np.zeros(1))  # updates so far (the replay's row)
        self._X_state = {
            side: self.DeclareAbstractState(AbstractValue.Make(RigidTransform(self._home[side])))
            for side in SIDES
        }
        self._lost = self.DeclareDiscreteState(np.ones(2))
        self._clipped = self.DeclareDiscreteState(np.zeros(2))
        self._tracker_state = self.DeclareDiscreteState(self._tracker.initial_state())
        for side in SIDES:
            self.DeclareStateOutputPort(f"X_TE_desired_{side}", self._X_state[side])
        self.DeclareStateOutputPort("tracking_lost", self._lost)
        self.DeclareStateOutputPort("workspace_clipped", self._clipped)
        self.DeclarePeriodicUnrestrictedUpdateEvent(
            period_sec=period_s,
            offset_sec=timing.stage_offset("mapper", stage_offset_s),
            update=self._update,
        )

    @property
    def mapping(self) -> RobotMapping:
        return self._mapping

    @property
    def hand_knuckles_replay(self) -> np.ndarray | None:
        """The replayed ``(frames, 2, 3)`` knuckle vectors, or None."""
        return self._replay

    @property
    def tracker(self) -> ControlFrameTracker:
        return self._tracker

    def home_pose(self, side: str) -> RigidTransform:
        """The home target of ``side``."""
        return RigidTransform(self._home[side])

    def _update(self, context, state) -> None:
        pose = self._input.Eval(context).reshape(NUM_LANDMARKS, 3)
        s = context.get_discrete_state(self._tracker_state).get_value()
        knuckles = None
        k = int(context.get_discrete_state(self._count).get_value()[0])
        if self._hands is not None and self._hands.HasValue(context):
            knuckles = self._hands.Eval(context).reshape(2, 3)
        elif self._replay is not None and len(self._replay):
            knuckles = self._replay[min(k, len(self._replay) - 1)]
        state.get_mutable_discrete_state(self._count).SetFromVector([k + 1.0])
        s, targets, lost, clipped = self._tracker.step(s, context.get_time(), pose, knuckles)
        for side, X in zip(SIDES, targets, strict=True):
            if X is not None:
                state.get_mutable_abstract_state(self._X_state[side]).set_value(_to_rigid_transform(X))
        state.get_mutable_discrete_state(self._tracker_state).SetFromVector(s)
        state.get_mutable_discrete_state(self._lost).SetFromVector(lost)
        state.get_mutable_discrete_state(self._clipped).SetFromVector(clipped)
