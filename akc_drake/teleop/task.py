"""The pick-and-place task of ``akc-drake demo --task pick-place``: scored per corrector over seeded runs.

Per seed, the operator's pick-and-place motion (:func:`~akc_drake.operator.motions.pick_place_plan`, varied by the
seed) is its plan. With the closed-loop operator (``operator="closed"``, the default) each corrector gets its own
run with the operator rendered in the loop: an :class:`~akc_drake.systems.operator_controller.OperatorController`
watches the robot's tool (and the carried box) and corrects its wrist target
(:mod:`akc_drake.operator.closed_loop`), MediaPipe (or the simulated detector) sees each rendered frame, and the
hands measured on the same frames command the gripper; given a Meshcat, the first seed's AKC(KF) run is recorded on
a page of its own (``pick_place.html`` in the demo's folder). With ``operator="open"`` the motion is rendered once
per seed and replayed through the teleop diagram with each corrector (the first seed's AKC(KF) run recorded in
Meshcat); the grippers follow the operator's pinch (:mod:`akc_drake.core.gripper`), the box is a free body with
contact. After the motion the robot holds its last targets for :data:`SETTLE_S` so the box comes to rest, and the
run is scored (:func:`score_box`): **success** when the box's centre ends within :data:`SUCCESS_RADIUS_M`
(horizontally) of the target's centre, resting on the table, **upright** (a face down: one of its axes within
:data:`UPRIGHT_TOL_DEG` of vertical) and **released** (no robot body touching it).

The hand channel: with ``--detector sim`` the simulated one (the motion's closure + noise,
:class:`~akc_drake.systems.gripper_command.HandApertureSource`); with ``--detector mediapipe`` MediaPipe Hands
(:class:`~akc_drake.io.hand_detector.HandDetector`) measures each rendered frame's hands (on the skinned body, whose
hands close with the motion) and those measurements command the grippers; the result then also reports the hand
channel against the truth (:func:`~akc_drake.core.gripper.hand_channel_report`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from akc_drake.robot.ik_status import quiet_drake_warnings
from akc_drake.teleop.scenario import (
    CORRECTORS,
    MAIN_CORRECTOR,
    make_meshcat,
    render_motion,
    run_teleop,
)

#: Task success: the box's centre within this horizontal distance of the target (metres).
SUCCESS_RADIUS_M = 0.03
#: Upright: one of the box's axes within this angle of the vertical (degrees).
UPRIGHT_TOL_DEG = 10.0
#: On the table: the box's centre within this height of resting on the table top (metres).
RESTING_TOL_M = 0.01
#: Seconds simulated after the motion before scoring (the robot holds its last targets).
SETTLE_S = 1.0
#: The table top's height and the box's half size (``models/teleop_scene.sdf``), metres.
TABLE_TOP_Z_M = 0.72
BOX_HALF_M = 0.025


@dataclass
class TaskOutcome:
    """One scored pick-and-place run.

    Attributes:
        seed, corrector: what was run.
        success: within the radius, resting, upright and released.
        box_error_cm: horizontal distance from the box's centre to the target's, cm.
        box_height_cm: height of the box's centre above resting on the table, cm (0: resting).
        upright, released, lifted: the criteria (lifted: the box left the table during the run... approximated
            by the box ending more than 3 cm from where it started).
        contacts: the bodies touching the box at the end.
        tilt_deg: the smallest angle between one of the box's axes and the vertical.
    """

    seed: int
    corrector: str
    success: bool
    box_error_cm: float
    box_height_cm: float
    upright: bool
    released: bool
    moved: bool
    contacts: tuple
    tilt_deg: float

    def as_dict(self) -> dict:
        return {
            "seed": self.seed,
            "corrector": self.corrector,
            "success": bool(self.success),
            "box_error_cm": float(self.box_error_cm),
            "box_height_cm": float(self.box_height_cm),
            "upright": bool(self.upright),
            "released": bool(self.released),
            "moved": bool(self.moved),
            "contacts": list(self.contacts),
            "tilt_deg": float(self.tilt_deg),
        }


def score_box(X_WB, target_W, start_W, contacts, *, seed: int = 0, corrector: str = "") -> TaskOutcome:
    """Score the box's final pose ``X_WB`` (4x4, world) against the target centre ``target_W`` (3,).

    Args:
        start_W: the box's starting centre (3,) (``moved``: it ended more than 3 cm away).
        contacts: names of the bodies touching the box.
    """
    X = np.asarray(X_WB, dtype=float)
    p = X[:3, 3]
    err = float(np.linalg.norm(p[:2] - np.asarray(target_W, float)[:2]))
    height = float(p[2] - (TABLE_TOP_Z_M + BOX_HALF_M))
    tilt = math.degrees(math.acos(min(1.0, float(np.max(np.abs(X[2, :3]))))))
    upright = tilt <= UPRIGHT_TOL_DEG
    robot = [c for c in contacts if c not in ("table", "floor")]
    released = not robot
    moved = float(np.linalg.norm(p - np.asarray(start_W, float))) > 0.03
    ok = err <= SUCCESS_RADIUS_M and abs(height) <= RESTING_TOL_M and upright and released
    return TaskOutcome(seed, corrector, ok, 100 * err, 100 * height, upright, released, moved, tuple(contacts), tilt)


def grasp_report(times, tool, obj, grasp_t: float) -> dict:
    """Where the robot's tool was against the box when the operator's hand began to close (the closed loop's
    report; what tells a missed grasp from a box pushed away on the robot's way in).

    Args:
        times: ``(n,)`` the operator's update times; tool, obj: ``(n, 3)`` the tool's and the box's positions it saw
            (in T); grasp_t: when the plan's hand first closes (same clock; inf: never).

    Returns:
        ``{"grasp_tool_minus_box_cm": [x, y, z], "box_moved_before_grasp_cm": horizontal distance from where the box
        was first seen}`` at the first update at or after ``grasp_t``; ``{}`` without a grasp or a box seen then.
    """
    times, tool, obj = np.asarray(times, float), np.asarray(tool, float), np.asarray(obj, float)
    if not len(times) or not np.isfinite(grasp_t) or grasp_t > times[-1]:
        return {}
    i = int(np.searchsorted(times, grasp_t - 1e-9))
    if not (np.all(np.isfinite(obj[i])) and np.all(np.isfinite(obj[0]))):
        return {}
    return {"grasp_tool_minus_box_cm": (100 * (tool[i] - obj[i])).round(2).tolist(),
            "box_moved_before_grasp_cm": float(100 * np.linalg.norm(obj[i, :2] - obj[0, :2]))}


class RememberingDetector:
    """A pose detector that keeps its last detection, so the hand channel can tell the hands apart by the pose's
    wrists (:func:`~akc_drake.core.gripper.hand_sides`)."""

    def __init__(self, inner):
        self.inner = inner
        self.name = inner.name
        self.last = None

    def __getattr__(self, name):  # needs_color, needs_label, close, ...
        return getattr(self.inner, name)

    def detect(self, frame):
        self.last = self.inner.detect(frame)
        return self.last

    def wrists_px(self):
        """``(2, 2)`` the last detection's left and right wrist pixels (None: nobody found)."""
        from akc_drake.core.skeleton import LANDMARKS

        if self.last is None or not self.last.person_found:
            return None
        return np.asarray(self.last.uv)[[LANDMARKS.index("left_wrist"), LANDMARKS.index("right_wrist")]]


def render_with_hands(motion, cfg, seed: int, progress, hand_detector):
    """Render ``motion`` through the render's own pose detector, running ``hand_detector`` (None: no hands) on
    each frame, the hands told apart by that frame's pose wrists.

    Returns:
        ``(session, recorder)``: the :class:`HandRecorder` holding the frames' hands (None without a detector).
    """
    if hand_detector is None:
        return render_motion(motion, cfg, seed=seed, progress=progress), None
    from akc_drake.systems.session_render import make_detector

    # the render's own pose detector (as render_session would make it), remembered for its wrists
    pose = RememberingDetector(make_detector(getattr(cfg, "detector", None), seed))
    recorder = HandRecorder(hand_detector, pose)
    try:
        session = render_motion(motion, cfg, seed=seed, progress=progress, frame_callback=recorder, detector=pose)
    finally:
        if hasattr(pose.inner, "close"):
            pose.inner.close()
    return session, recorder


class HandRecorder:
    """A render's frame callback: the hand detector on each frame, the thumb-index distances collected.

    Args:
        detector: a :class:`~akc_drake.io.hand_detector.HandDetector`.
        pose: the render's :class:`RememberingDetector` (its wrists tell the hands apart), or None.
    """

    def __init__(self, detector, pose: RememberingDetector | None = None):
        self.detector = detector
        self.pose = pose
        self.rows: list[np.ndarray] = []
        self.knuckle_rows: list[np.ndarray] = []

    def __call__(self, frame) -> None:
        from akc_drake.core.control_frames import hands_knuckle_vector

        wrists = self.pose.wrists_px() if self.pose is not None else None
        found = self.detector.detect(frame, wrists)
        self.rows.append(found.aperture_m)
        self.knuckle_rows.append(np.array([hands_knuckle_vector(h, frame.intrinsics) for h in found.landmarks_px]))

    @property
    def apertures(self) -> np.ndarray:
        """``(frames, 2)`` thumb-index distances (left, right; metres; NaN: not found)."""
        return np.array(self.rows, dtype=float).reshape(-1, 2)

    @property
    def knuckles(self) -> np.ndarray:
        """``(frames, 2, 3)`` each hand's knuckle vector in normalised image units
        (:func:`~akc_drake.core.control_frames.hands_knuckle_vector`; NaN: not found), for the wrist frames."""
        return np.array(self.knuckle_rows, dtype=float).reshape(-1, 2, 3)


def hand_truth(motion, times, params=None) -> np.ndarray:
    """``(T, 2)`` the skinned operator's true thumb-index distances at ``times`` (seconds from the start)."""
    from akc_drake.operator.skinned import skinned_operator

    body = skinned_operator(params)
    return np.array([body.pinch_aperture(c) for c in motion.closure(motion.start + np.asarray(times))])


def _hand_report(motion, times, apertures, cfg, seed: int, log) -> dict:
    """The hand channel's report for one seed's rendered frames (MediaPipe Hands against the truth), logged."""
    from akc_drake.core.gripper import hand_channel_report

    truth = hand_truth(motion, times) if getattr(cfg, "body", "") == "skinned" else np.full(apertures.shape, np.nan)
    intended = motion.closure(motion.start + times) > 0.5
    report = {"seed": seed, **hand_channel_report(apertures, truth, intended, times)}
    r = report["right"]
    log(f"  pick-place seed {seed} hands (MediaPipe): right found {100 * r['found']:.0f} %, gripper "
        f"state as intended {100 * r['state_agreement']:.0f} %, switch delays {r['switch_delay_s']} s")
    return report


def _closed_loop_run(cfg, calib, corrector, planned, mapping, landmarks, seed, progress, hand_detector,
                     meshcat=None):
    """One closed-loop run: the operator (:class:`~akc_drake.operator.closed_loop.ClosedLoopOperator`, ``planned``
    the motion and its :class:`~akc_drake.operator.motions.ToolPlan`) rendered in the loop, watching the robot's
    tool; the pose detector is ``cfg.detector``'s (seeded by ``seed``), the hands MediaPipe Hands' on the same
    frames (``hand_detector``) or the simulated channel; drawn in ``meshcat`` (its own recording, from time 0: the
    rendered operator and the controller run on the simulation's clock) when given."""
    import dataclasses

    from akc_drake.operator.closed_loop import ClosedLoopOperator
    from akc_drake.systems.session_render import make_detector

    motion, plan = planned
    from akc_drake.operator.motions import PICK_BOX_T

    core = ClosedLoopOperator(motion, mapping, landmarks=landmarks, tool_plan=plan, object_T=PICK_BOX_T)
    detector = make_detector(getattr(cfg, "detector", None), seed)
    try:
        return run_teleop(dataclasses.replace(cfg, seed=seed), calib.dims, corrector=corrector, motion=motion,
                          torso_model=calib.torso, settle_s=SETTLE_S, progress=progress, operator=core,
                          detector=detector, hand_detector=hand_detector, meshcat=meshcat)
    finally:
        if hasattr(detector, "close"):
            detector.close()


def _recorded_closed_loop_run(*args) -> tuple:
    """:func:`_closed_loop_run` drawn and recorded in a Meshcat of its own: ``(run, diagram, html)`` (html None when
    Meshcat cannot start). The closed loop renders the operator on the simulation's clock, so it cannot be appended
    after the demo's recorded replays (which start later); it gets its own page."""
    meshcat, _ = make_meshcat()
    if meshcat is None:  # a port range in use, no sockets allowed, ...
        return (*_closed_loop_run(*args), None)
    meshcat.StartRecording(set_visualizations_while_recording=False)
    run, td = _closed_loop_run(*args, meshcat)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    return run, td, meshcat.StaticHtml()


def _world_from_T(p_T) -> np.ndarray:
    """A point of the robot torso frame T in the world (the base is welded at the origin, T at 1.10 m)."""
    return np.asarray(p_T, dtype=float) + np.array([0.0, 0.0, 1.10])


def run_pick_place(
    cfg,
    calib,
    seeds: int,
    *,
    correctors: tuple[str, ...] = tuple(CORRECTORS),
    progress: bool = False,
    log: Callable[[str], None] = print,
    meshcat=None,
    start_time: float = 0.0,
    hand_model=None,
    hands: str | None = None,
    operator: str = "closed",
) -> dict:
    """Run the task ``seeds`` times per corrector.

    Args:
        cfg: the pipeline configuration; calib: the demo's T-pose :class:`~akc_drake.teleop.scenario.Calibration`.
        seeds: number of seeded runs (seeds 0 .. seeds - 1).
        meshcat, start_time: draw (and record) the first seed's AKC(KF) run in this Meshcat, starting at this
            simulation time (after the demo's recorded runs); with the closed-loop operator, given a Meshcat, that
            run is recorded in a Meshcat of its own instead (its page in the result's ``"recording_html"``).
        hand_model: MediaPipe Hands' ``.task`` file (None: the packaged one).
        hands: the hand channel, "sim" (the motion's closure + noise) or "mediapipe" (MediaPipe Hands on the
            rendered frames); None: "mediapipe" when ``cfg.detector`` is, else "sim".
        operator: "closed" (default): the operator watches the robot's tool and corrects it
            (:mod:`akc_drake.operator.closed_loop`), so each corrector's run renders the operator in the loop;
            "open": the motion is rendered once per seed and its measurements replayed to every corrector.

    Returns:
        ``{"runs": [outcome dicts], "success_rate": {corrector: share}, "wall_s": ...}``; with MediaPipe's
        hand channel also ``"hands"``: per seed, the hand channel's report; with the closed loop recorded,
        ``"recording_html"``: its Meshcat page (a string, for the caller to write).
    """
    from akc_drake.core.frames import calibrated_mapping
    from akc_drake.diagrams import Measurements
    from akc_drake.operator.motions import PICK_BOX_T, PLACE_TARGET_T, pick_place_plan

    t0 = time.perf_counter()
    target_W, start_W = _world_from_T(PLACE_TARGET_T), _world_from_T(PICK_BOX_T)
    outcomes: list[TaskOutcome] = []
    reports = []
    hands = hands or ("mediapipe" if getattr(cfg, "detector", "sim") == "mediapipe" else "sim")
    if hands not in ("sim", "mediapipe"):
        raise ValueError(f"hands must be sim or mediapipe, got {hands!r}")
    hand_detector = None
    if hands == "mediapipe":
        from akc_drake.io.hand_detector import HandDetector

        hand_detector = HandDetector(hand_model)
    # The operator holds the hand the camera sees so that the robot's tool is right: on the skinned body, the rig's
    # hand (its knuckles, which set the wrist frame, are not the operator model's).
    landmarks = None
    if getattr(cfg, "body", "primitive") == "skinned":
        from akc_drake.operator.skinned import skinned_operator

        landmarks = skinned_operator().landmarks_O
    if operator not in ("open", "closed"):
        raise ValueError(f"operator must be open or closed, got {operator!r}")
    offsets = []
    html = None
    with quiet_drake_warnings():
        for seed in range(int(seeds)):
            # The operator works with the mapping the pipeline uses (calibrated from the T-pose).
            mapping = calibrated_mapping(calib.dims)
            motion, plan = pick_place_plan(seed, mapping=mapping, landmarks=landmarks)
            apertures = knuckles = meas = None
            if operator == "open":
                session, recorder = render_with_hands(motion, cfg, seed, progress, hand_detector)
                meas = Measurements.from_session(session)
                if recorder is not None:
                    apertures, knuckles = recorder.apertures, recorder.knuckles
                    reports.append(_hand_report(motion, session.t, apertures, cfg, seed, log))
            for corrector in correctors:
                record = meshcat is not None and seed == 0 and corrector == MAIN_CORRECTOR and operator == "open"
                if operator == "open":
                    run, _ = run_teleop(cfg, calib.dims, corrector=corrector, replay=meas, motion=motion,
                                        torso_model=calib.torso, settle_s=SETTLE_S, progress=progress,
                                        meshcat=meshcat if record else None,
                                        start_time=start_time if record else 0.0, hand_apertures=apertures,
                                        hand_knuckles=knuckles)
                elif meshcat is not None and seed == 0 and corrector == MAIN_CORRECTOR:
                    run, td, html = _recorded_closed_loop_run(cfg, calib, corrector, (motion, plan), mapping,
                                                              landmarks, seed, progress, hand_detector)
                else:
                    run, td = _closed_loop_run(cfg, calib, corrector, (motion, plan), mapping, landmarks, seed,
                                               progress, hand_detector)
                if operator == "closed":  # the recorded run too (before, its line showed the previous run's)
                    t_c, c = td.operator.offsets()
                    grasp = grasp_report(*td.operator.watched(), td.operator.grasp_time())
                    offsets.append({"seed": seed, "corrector": corrector,
                                    "final_offset_cm": (100 * c[-1]).tolist() if len(c) else None,
                                    "max_offset_cm": float(100 * np.max(np.linalg.norm(c, axis=1))) if len(c)
                                    else 0.0, "wall_s": float(run.wall_s), **grasp})
                out = score_box(run.box_pose, target_W, start_W, run.box_contacts, seed=seed, corrector=corrector)
                outcomes.append(out)
                log(
                    f"  pick-place seed {seed} {corrector:9s}: {'success' if out.success else 'failure'} "
                    f"(box {out.box_error_cm:.1f} cm from the target, {out.box_height_cm:+.1f} cm high, "
                    f"tilt {out.tilt_deg:.0f} deg, {'released' if out.released else 'held'}"
                    + (f"; operator's correction up to {offsets[-1]['max_offset_cm']:.1f} cm, run {run.wall_s:.0f} s"
                       if operator == "closed" else "")
                    + (f"; at the grasp the tool {np.round(offsets[-1]['grasp_tool_minus_box_cm'], 1).tolist()} cm "
                       f"from the box, moved {offsets[-1]['box_moved_before_grasp_cm']:.1f} cm before"
                       if operator == "closed" and "grasp_tool_minus_box_cm" in offsets[-1] else "") + ")"
                )
    if hand_detector is not None:
        hand_detector.close()
    rates = {c: float(np.mean([o.success for o in outcomes if o.corrector == c])) for c in correctors}
    return {
        **({"recording_html": html} if html is not None else {}),
        **({"hands": reports} if reports else {}),
        "task": "pick-place",
        "operator": operator,
        **({"operator_corrections": offsets} if offsets else {}),
        "seeds": int(seeds),
        "target_W": target_W.tolist(),
        "success_radius_cm": 100 * SUCCESS_RADIUS_M,
        "runs": [o.as_dict() for o in outcomes],
        "success_rate": rates,
        "wall_s": time.perf_counter() - t0,
    }
