"""The ``akc-drake`` command line.

Each subcommand's options are declared here (they are a contract people script against, see
DESIGN.md); its work is done by ``akc_drake.commands.<name>.main(args) -> int``. A user mistake
raises :class:`~akc_drake.errors.UserError` (or ``ValueError`` from input validation) and becomes
one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys

from akc_drake import __version__
from akc_drake.errors import UserError

METHODS = ("Raw", "KF", "EKF", "COIK(KF)", "AKC(KF)", "AKC(EKF)", "AKC+(KF)", "AKC+(EKF)", "COIK(EKF)")

# Subcommand -> the issue that builds it (for the "not available yet" message).
_PENDING_ISSUE = {
    "demo": 5,
    "evaluate": 6,
    "sweep": 6,
    "graph": 4,
    "record": 3,
    "run": 4,
    "calibrate": 7,
    "bench": 8,
    "soak": 9,
}


class _HelpFormatter(argparse.HelpFormatter):
    """Shows each option's default (``(default: X)``) unless its help already states it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "default" not in text
            and action.option_strings
            and default is not None
            and default is not False
            and default is not argparse.SUPPRESS
        ):
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line on stderr (naming the option) and exit code 2."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # noqa: D102 - argparse's hook
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _seed(text: str) -> int:
    """``--seed``: a non-negative integer (numpy's generators reject negative seeds)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {value}")
    return value


def _add_joint_names(p) -> None:
    """``--joint-names``: the roles a motion file names differently (evaluate, record, run)."""
    p.add_argument("--joint-names", metavar="MAP",
                   help="the motion file's joints for roles the usual names miss: role=joint[,role=joint...] or a "
                        "JSON file (roles: left_shoulder, left_elbow, left_wrist, right_..., hips; BVH, CMU, "
                        "Blender, Unreal, Kinect and Motive names are found without it)")


def _add_akc_plus(p) -> None:
    """``--akc-plus``: AKC+ settings (evaluate, run)."""
    p.add_argument("--akc-plus", metavar="SETTINGS",
                   help="AKC+ settings (AKCPlusConfig fields): field=value[,field=value...] or a JSON file, e.g. "
                        "gate_sigma=2.5,nis_alpha=0.1 (constrained_filter=true|false overrides the choice made from "
                        "the filter)")


def _add_seed(p: argparse.ArgumentParser, what: str = "the motion variation, detector and depth noise") -> None:
    p.add_argument("--seed", type=_seed, default=0, metavar="S", help=f"random seed of {what}")


POSE_MODEL_HELP = ("MediaPipe's pose model: heavy (the most accurate end-on) | full (faster) | lite | PATH to a "
                   "pose_landmarker .task file (default: $AKC_DRAKE_POSE_MODEL, else heavy; full if heavy is not "
                   "installed)")


def _add_source_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--source",
        default="sim",
        help="sim | recording:DIR | bag:FILE | realsense | video:FILE (default: sim)",
    )
    p.add_argument("--dims", metavar="FILE.json", help="calibrated body dimensions (from 'akc-drake calibrate')")
    p.add_argument("--pose-model", metavar="MODEL", help=POSE_MODEL_HELP)
    p.add_argument("--depth", type=float, metavar="M", help="constant depth in metres for video:FILE sources")
    p.add_argument("--config", metavar="FILE.yaml", help="a diagram configuration file (YAML)")


def _add_scheduler_args(p: argparse.ArgumentParser, workers: bool = True) -> None:
    p.add_argument(
        "--scheduler",
        default="local",
        metavar="S",
        help="local (a Dask LocalCluster on this machine, default) | inprocess | tcp://HOST:PORT (a Dask cluster)",
    )
    if workers:
        p.add_argument("--workers", type=int, metavar="N", help="local worker processes (default: one per core)")


def _body_detector(p, both: bool = False, body: str = "primitive", detector: str = "sim") -> None:
    """``--body`` and ``--detector``: the simulated operator and the detector that looks at it (``both``:
    also offer ``--detector both``, the simulated detector and MediaPipe side by side); ``body``, ``detector``:
    the defaults."""
    p.add_argument("--body", default=body, choices=("primitive", "skinned"),
                   help=f"simulated operator: primitive (fast) or skinned (MakeHuman body; default: {body})")
    p.add_argument("--detector", default=detector,
                   choices=("sim", "mediapipe", "both") if both else ("sim", "mediapipe"),
                   help=f"2D detector on the renders: sim (simulated) or mediapipe (default: {detector})"
                   + ("; both: the tables with each, side by side" if both else ""))
    if "--pose-model" not in p._option_string_actions:  # run and calibrate have it with their sources
        p.add_argument("--pose-model", metavar="MODEL", help=POSE_MODEL_HELP)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="akc-drake",
        description="Markerless RGB-D arm motion capture with Arm Kinematic Correction, as a Drake diagram.",
    )
    parser.add_argument("--version", action="version", version=f"akc-drake {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("demo", help="teleoperate the simulated robot from the rendered operator (the main job)")
    p.add_argument("--quick", action="store_true", help="one cycle of each motion (CI-sized; default: 3 cycles)")
    p.add_argument("--dropout", type=float, default=0.0, metavar="F",
                   help="share of frames lost in bursts, 0-1 (default: 0)")
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output folder (default: out/demo)")
    p.add_argument("--json", metavar="FILE", help="also write the summary (demo.json) to FILE")
    p.add_argument("--meshcat", action="store_true", help="serve Meshcat on localhost while running")
    p.add_argument("--html", metavar="FILE", help="save the Meshcat recording as a standalone HTML page")
    p.add_argument("--ros2-bag", metavar="FILE.mcap", help="write the AKC(KF) replays as a ROS 2 MCAP bag")
    _add_seed(p, "the renders, the detector, the depth noise and --dropout")
    p.add_argument("--task", choices=("pick-place",), help="also run a task and score it per corrector")
    p.add_argument("--seeds", type=int, default=5, metavar="N", help="seeded runs of --task per corrector (default: 5)")
    p.add_argument("--operator", choices=("closed", "open"), default="closed",
                   help="--task's operator: closed (watches the robot's tool and corrects it, rendered in the loop per "
                        "corrector; default) or open (its motion rendered once per seed and replayed)")
    p.add_argument("--hand-model", metavar="PATH",
                   help="MediaPipe hand_landmarker .task file (the gripper's hand channel with --detector mediapipe)")
    # The main job shows the real pipeline: MediaPipe on the rendered skinned body (--body primitive --detector sim:
    # the fast simulated path).
    _body_detector(p, body="skinned", detector="mediapipe")

    p = sub.add_parser("evaluate", help="reproduce the paper's tables and figures against ground truth")
    p.add_argument("--motion", default="both", choices=("I", "II", "both"), help="the paper's motion(s)")
    p.add_argument("--motion-file", metavar="FILE", help="a BVH or C3D file, or an AMC file with --skeleton")
    p.add_argument("--skeleton", metavar="FILE.asf", help="the ASF skeleton for an AMC motion file")
    _add_joint_names(p)
    p.add_argument("--cycles", type=int, default=30, metavar="N", help="motion cycles of 6 s each")
    _add_seed(p)
    p.add_argument("--methods", default=None, help="comma-separated, from: " + ", ".join(METHODS)
                   + ", and NAME(KF), NAME(EKF) for an --add-corrector NAME (default: all; with --motion-dir: KF, "
                   "EKF and the AKC/AKC+ variants; and each --add-corrector's two)")
    p.add_argument("--weights", default="Wb", choices=("Wa", "Wb", "Wc"), help="AKC weight preset (paper Table I)")
    p.add_argument("--rate-hz", type=float, default=10.0, metavar="HZ",
                   help="the camera's frame rate (default: 10, the paper's; a RealSense streams at 30); motion "
                   "files and the --motion-dir clips are retargeted at it")
    p.add_argument("--camera", default="default", metavar="PLACEMENT",
                   help="where the simulated camera stands, metres from the operator's pelvis: default (2 m in "
                   "front, 0.45 m up, level) or distance_m=D,height_m=H,lateral_m=L (to the operator's left),"
                   "aim_height_m=A (it faces the operator's vertical axis, aimed A above the pelvis; default level), "
                   "fields left out the default's, or a JSON file; the calibration T-pose is rendered from it too")
    p.add_argument("--depth-noise", default="default", metavar="MODEL",
                   help="the simulated camera's depth error model: default (sub-pixel disparity noise 0.08 px, "
                   "independent per pixel: a joint's 15-pixel depth window averages it to about 0.1 cm at 2 m) or "
                   "field=value,... of sigma_disparity_px, correlation_px (the noise's correlation length: at 4 a "
                   "window keeps two thirds of it, as a real stereo camera's does), baseline_m, edge_width_px, "
                   "edge_disparity_px, min_depth_m, max_depth_m; or a JSON file; the calibration T-pose too")
    p.add_argument("--body-scale", type=float, default=1.0, metavar="K",
                   help="the rendered operator's size: every length times K, 0.6-1.4 (default 1: the paper's "
                   "participant); the calibration T-pose too")
    _add_akc_plus(p)
    p.add_argument("--add-corrector", action="append", metavar="NAME=FILE.py:FACTORY",
                   help="a corrector of your own, run as NAME(KF) and NAME(EKF) beside the others (added to the "
                   "default --methods) and compared with its filter as AKC+ is: FACTORY(dims, filter_kind, "
                   "period_s) returns an object whose correct(pose, measured, variance) returns the corrected "
                   "(12, 3) pose; FILE.py or package.module (see the README, 'Your own corrector'); repeatable")
    p.add_argument("--protocol", default="paper", choices=("paper", "ours"),
                   help="paper: the stages and table definitions as the paper describes them; ours: our "
                   "improvements (default: paper)")
    p.add_argument("--filter-settings", metavar="SETTINGS",
                   help="the KF's and the EKF's settings changed from the protocol's: teleop (the teleop "
                   "diagram's gate and prediction), field=value[,...] (KFConfig fields, e.g. "
                   "gate_sigma=5,gate_speed_m_s=6,max_predict_s=0.3), the two (teleop,gate_speed_m_s=0) or a "
                   "JSON file")
    p.add_argument("--motion-dir", metavar="DIR", help="evaluate on every real mocap clip of DIR (e.g. data/mocap "
                   "from 'make mocap-data'): per-clip and pooled tables, a plot per clip and method")
    p.add_argument("--drive", default="angles", choices=("angles", "rig"),
                   help="how a clip (--motion-file or --motion-dir) poses --body skinned: angles (the "
                   "operator's 10 arm angles, torso fixed; default) or rig (bone by bone: spine, clavicles, neck, "
                   "head too; a rig without CMU's bone names is mapped by role, --joint-names helps it)")
    p.add_argument("--export", metavar="FMT[,FMT]", help="also write every method's skeleton to --out/exports as "
                   "bvh | trc | c3d | csv, and the RTS smoother's gain (rts_gain.json)")
    p.add_argument("--export-frame", default="world", choices=("world", "camera"), help="frame of --export files")
    p.add_argument("--out", metavar="DIR", help="write report.md, CSV tables and PNG figures here")
    p.add_argument("--json", metavar="FILE", help="write the tables as JSON (DESIGN.md keys)")
    p.add_argument("--width", type=int, default=640, help=argparse.SUPPRESS)
    p.add_argument("--height", type=int, default=480, help=argparse.SUPPRESS)
    _body_detector(p, both=True)
    _add_scheduler_args(p)

    p = sub.add_parser("sweep", help="AKC weight and shrink-factor sensitivity study (paper Fig. 5, Table VII)")
    p.add_argument("--motion", default="both", choices=("I", "II", "both"), help="the paper's motion(s)")
    p.add_argument("--cycles", type=int, default=30, metavar="N", help="motion cycles of 6 s each")
    p.add_argument("--jobs", "--workers", dest="jobs", type=int, default=2, metavar="N",
                   help="local worker processes (--workers: the same, as in evaluate; default: 2)")
    _add_scheduler_args(p, workers=False)
    _add_seed(p)
    p.add_argument("--out", metavar="DIR", help="write sweep.md, tables/table7.csv and the figures here")
    p.add_argument("--json", metavar="FILE", help="write the grid, the optima and Table VII as JSON")

    p = sub.add_parser("compare", help="real-motion evaluations side by side, and what changed between two")
    p.add_argument("runs", nargs="+", metavar="RUN.json|DIR",
                   help="JSONs of `evaluate --motion-dir DIR --json FILE`, or folders of them")
    p.add_argument("--against", nargs="+", metavar="OLD.json|DIR",
                   help="an earlier run of the same clips per run, in order (or one folder: paired by file name): "
                        "print what changed")
    p.add_argument("--methods", metavar="M,M", help="only these corrected methods (default: every one the runs have)")
    p.add_argument("--target", type=float, default=0.5, metavar="CM",
                   help="the increase over the filter counted as a miss (default 0.5 cm)")
    p.add_argument("--min-change", type=float, default=0.1, metavar="CM",
                   help="with --against, list every clip, joint and axis that moved by this much (default 0.1 cm)")
    p.add_argument("--json", metavar="FILE", help="write the rows and the changes as JSON")

    p = sub.add_parser("cache", help="where the render cache is and how big; --clear empties it")
    p.add_argument("--clear", action="store_true", help="delete every cached rendered session")

    p = sub.add_parser("graph", help="write the system graph of a diagram as .dot and .svg")
    p.add_argument("--diagram", required=True, choices=("mocap", "teleop"), help="which diagram (required)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for NAME.dot and NAME.svg (required)")

    p = sub.add_parser("record", help="render (or capture) a session into a recording folder")
    p.add_argument("--motion", default="II", help="I | II | tpose | lpose | FILE.bvh | FILE.c3d | FILE.amc")
    p.add_argument("--skeleton", metavar="FILE.asf", help="the ASF skeleton for an AMC motion file")
    _add_joint_names(p)
    p.add_argument("--source", default="sim", help="sim | realsense | bag:FILE (default: sim)")
    p.add_argument("--cycles", type=int, default=1, metavar="N", help="motion cycles of 6 s each (--source sim)")
    _add_seed(p)
    p.add_argument("--seconds", type=float, metavar="S", help="duration for live or bag sources (default: all)")
    p.add_argument("--out", required=True, metavar="DIR", help="the recording folder to write (required)")
    _body_detector(p)

    p = sub.add_parser("run", help="run the mocap (or teleop) diagram on a source")
    _add_source_args(p)
    p.add_argument("--motion", default="II",
                   help="motion for --source sim: I | II | tpose | lpose | FILE.bvh | FILE.c3d | FILE.amc")
    p.add_argument("--skeleton", metavar="FILE.asf", help="the ASF skeleton for an AMC --motion file")
    _add_joint_names(p)
    p.add_argument("--cycles", type=int, default=1, metavar="N", help="motion cycles of 6 s each (--source sim)")
    _add_seed(p)
    p.add_argument("--filter", default="KF", choices=("none", "KF", "EKF"), help="the landmark filter")
    p.add_argument("--corrector", default="AKC", choices=("none", "AKC", "AKC+", "COIK"),
                   help="the arm correction after the filter")
    _add_akc_plus(p)
    p.add_argument("--teleop", action="store_true", help="drive the simulated robot too")
    p.add_argument("--meshcat", action="store_true", help="with --teleop: serve Meshcat on localhost")
    p.add_argument("--arm-limits", metavar="LIMITS",
                   help="with --teleop: the arms' joint acceleration and jerk limits (rad/s^2, rad/s^3) the commands "
                        "keep to: acceleration=A,jerk=J (every joint; a field left out is the model's), a JSON file "
                        "(7 numbers each) or off (no limiter); default: the config's arm_limits, else the model's")
    p.add_argument("--seconds", type=float, metavar="S", help="stop after this long (live sources; default: "
                   "the whole source)")
    p.add_argument("--out", metavar="DIR", help="where to write poses.npz (default: --json's folder, else out/run)")
    p.add_argument("--export", metavar="FMT[,FMT]", help="also write the raw, filtered and corrected skeletons to "
                   "--out as bvh | trc | c3d | csv (see 'akc-drake export')")
    p.add_argument("--export-frame", default="world", choices=("world", "camera"), help="frame of --export files")
    p.add_argument("--smooth", default="none", choices=("none", "rts"), help="--export with RTS smoothing")
    p.add_argument("--ros2-bag", metavar="FILE.mcap", help="write a ROS 2 MCAP bag: skeletons, control frames and, "
                   "with --teleop, the robot's joint commands and wrist targets")
    p.add_argument("--lcm", metavar="URL", help="with --teleop: publish joint commands and wrist targets on LCM "
                   "(memq://, udpm://239.255.76.67:7667 (ttl=0: this host only), file://LOG?mode=w)")
    p.add_argument("--json", metavar="FILE", help="write the summary as JSON (frames, latency, errors)")
    _body_detector(p)

    p = sub.add_parser("calibrate", help="arm lengths and shoulder width from a held T-pose or L-pose")
    _add_source_args(p)
    p.add_argument("--pose", default="tpose", choices=("tpose", "lpose"), help="the held calibration pose")
    p.add_argument("--frames", type=int, default=100, metavar="N", help="calibration frames, at least 10")
    p.add_argument("--out", required=True, metavar="FILE.json",
                   help="where to write the dimensions (required; read by --dims)")
    _body_detector(p)

    p = sub.add_parser("soak", help="a long simulated teleop session with random tracking loss (robustness)")
    p.add_argument("--minutes", type=float, default=30.0, metavar="M", help="simulated minutes (default: 30)")
    p.add_argument("--dropout", type=float, default=0.3, metavar="F", help="share of frames lost in bursts, 0-1")
    p.add_argument("--garbage", type=float, default=0.0, metavar="F", help="share of frames with garbage, 0-1")
    p.add_argument("--motion", default="I", choices=("I", "II"), help="the motion, repeated")
    _add_seed(p, "the motion variation and the tracking-loss bursts")
    p.add_argument("--sample-s", type=float, default=10.0, metavar="S", help=argparse.SUPPRESS)
    p.add_argument("--json", metavar="FILE", help="write the checks and figures as JSON")

    p = sub.add_parser("bench", help="measure the speed of every stage (see README, Performance)")
    p.add_argument("--quick", action="store_true", help="the CI-sized run (well under a minute)")
    _body_detector(p)
    p.add_argument("--json", metavar="FILE", help="write every figure as JSON (DESIGN.md keys)")

    p = sub.add_parser("export", help="a poses.npz (from run) to BVH, TRC, C3D, CSV or a ROS 2 MCAP bag")
    p.add_argument("--poses", required=True, metavar="FILE.npz", help="the poses.npz that 'run' writes (required)")
    p.add_argument("--format", required=True, metavar="FMT", help="bvh | trc | c3d | csv | mcap (required)")
    p.add_argument("--out", required=True, metavar="FILE", help="the file to write (required)")
    p.add_argument("--stage", default="corrected", metavar="S",
                   help="raw | accepted | filtered | corrected | truth (default: corrected)")
    p.add_argument("--frame", default="world", choices=("world", "camera"),
                   help="world: gravity-aligned, floor at z=0 (default); camera: the camera frame")
    p.add_argument("--calibration", metavar="FILE.npz", help="a T-pose poses.npz to estimate the world frame from")
    p.add_argument("--smooth", default="none", choices=("none", "rts"),
                   help="rts: zero-phase Rauch-Tung-Striebel smoothing in place of the forward KF (offline)")
    p.add_argument("--dims", metavar="FILE.json", help="calibrated body dimensions (default: those in the npz)")
    p.add_argument("--json", metavar="FILE", help="write a summary (world frame, RTS gain with ground truth)")

    return parser


def _use_pose_model(model, detector=None) -> None:
    """``--pose-model``: checked, then made every MediaPipe pose detector's default in this process and the
    worker processes it starts (``$AKC_DRAKE_POSE_MODEL``; the render cache keys the file it names). Without it,
    a MediaPipe run resolves the default here, before any worker starts (a missing heavy model: one warning)."""
    if not model and detector in ("mediapipe", "both"):
        from akc_drake.io.mediapipe_detector import find_pose_model

        with contextlib.suppress(UserError):  # no model at all: the command says so where it needs one
            find_pose_model()
    if model:
        from akc_drake.io.mediapipe_detector import find_pose_model
        from akc_drake.io.pose_models import POSE_MODEL_ENV, POSE_MODELS

        path = find_pose_model(model)
        os.environ[POSE_MODEL_ENV] = model if model in POSE_MODELS else str(path.resolve())


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        module = importlib.import_module(f"akc_drake.commands.{args.command}")
    except ModuleNotFoundError as e:
        if e.name != f"akc_drake.commands.{args.command}":
            raise
        issue = _PENDING_ISSUE.get(args.command)
        print(
            f"akc-drake {args.command}: not available yet (it lands with issue {issue}).",
            file=sys.stderr,
        )
        return 2
    try:
        _use_pose_model(getattr(args, "pose_model", None), getattr(args, "detector", None))
        return int(module.main(args) or 0)
    except (UserError, ValueError, OSError) as e:
        if isinstance(e, OSError) and not e.filename:
            raise  # not a path the user gave (a socket, a worker): a bug or an environment problem, with its traceback
        msg = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) else str(e)
        print(f"akc-drake {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"akc-drake {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
