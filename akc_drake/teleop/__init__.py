"""The demo's logic: teleoperate the simulated robot from the rendered operator; compare the correctors.

:func:`run_demo` does the whole job of ``akc-drake demo``:

1. **Calibrate** from a rendered T-pose: its first 100 frames, through the occlusion filter and the KF (the
   mocap diagram on a replay), averaged by :func:`~akc_drake.core.calibration.calibrate_report`.
2. **Render** Motion I and Motion II once each
   (:func:`~akc_drake.systems.depth_camera_source.render_session`). With ``dropout > 0``, the same bursts of
   lost frames (the whole person, 0.5-3 s each, seeded: :func:`akc_drake.faults.inject_dropouts`) are
   blanked in every corrector's replay.
3. **Teleoperate** the robot with each corrector (:data:`CORRECTORS`: Raw, KF, AKC(KF), AKC+(KF), COIK(KF)) by
   replaying the same measurements through the teleop diagram, and once more with the AKC(KF) pipeline
   *rendering* its camera frames inside the diagram (the realtime factor of the full pipeline).
4. **Report**: a table per motion and pooled (:func:`format_table`), ``demo.json``, the end-effector paths
   and the tracking error over time (PNG), the Meshcat recording of the AKC(KF) runs as a standalone HTML
   page and the teleop diagram's graph (.dot/.svg).

What is measured (the robot side of the loop, :class:`~akc_drake.systems.teleop_monitor.TeleopMonitor`):

* **End-effector tracking error**: distance between the mapped target ``X_TE_desired`` (the FrameMapper's
  output, before the IK's reach guard) and the achieved end-effector position, sampled once per camera
  frame at the end of the frame's period (``t_k + 0.09 s``). The first target jumps from the robot's home
  pose to the operator's mapped wrist, so the headline ``ee_tracking_error_cm`` is the median **after the
  first second** (:data:`SETTLING_S`); ``ee_tracking_error_cm_with_settling`` includes it.
* **Error to the operator**: distance between the achieved end effector and the operator's *true* wrist
  mapped to the robot (the ground truth through the same mapping), same samples: what correctors are for.
* **Control-frame jitter**: RMS angular (rad/s) and linear (m/s) speed of ``X_TE_desired`` between
  consecutive camera frames (:func:`~akc_drake.core.frames.frame_jitter`), after the first second; the
  operator's true mapped wrist gives the reference (the motion's own speed).
* **Limit hits**: IK-period samples where a commanded joint is within 1e-3 rad of a position limit, or where
  a joint's commanded step reaches 97 % of its velocity limit (counted per arm).
* **IK failures**: differential-IK steps (100 Hz, per arm) whose status was not "solution found" ("no
  solution" or "stuck"). Counted by :class:`IKStatusCounter`, a simulator monitor that reads each
  integrator's status once after every IK update.
* **NaN commands**: IK-period samples where a joint command was not finite (must be 0).
* **Realtime factor**: simulated seconds / wall-clock seconds of ``simulate`` (construction excluded).
"""

from akc_drake.robot.ik_status import IKStatusCounter, quiet_drake_warnings
from akc_drake.teleop.demo import DemoOptions, run_demo
from akc_drake.teleop.metrics import pooled_jitter, run_metrics
from akc_drake.teleop.report import format_table, plot_errors, plot_paths
from akc_drake.teleop.scenario import (
    CALIBRATION_FRAMES,
    CORRECTORS,
    DROPOUT_BURST_S,
    FULL_CYCLES,
    MAIN_CORRECTOR,
    MOTIONS,
    QUICK_CYCLES,
    RECORDING_GAP_S,
    SETTLING_S,
    SIDES,
    Calibration,
    TeleopRun,
    calibrate_from_tpose,
    make_meshcat,
    operator_targets,
    render_motion,
    run_teleop,
    truncate_motion,
)

__all__ = [
    "CALIBRATION_FRAMES",
    "CORRECTORS",
    "DROPOUT_BURST_S",
    "FULL_CYCLES",
    "MAIN_CORRECTOR",
    "MOTIONS",
    "QUICK_CYCLES",
    "RECORDING_GAP_S",
    "SETTLING_S",
    "SIDES",
    "Calibration",
    "DemoOptions",
    "IKStatusCounter",
    "TeleopRun",
    "calibrate_from_tpose",
    "format_table",
    "make_meshcat",
    "operator_targets",
    "plot_errors",
    "plot_paths",
    "pooled_jitter",
    "quiet_drake_warnings",
    "render_motion",
    "run_demo",
    "run_metrics",
    "run_teleop",
    "truncate_motion",
]
