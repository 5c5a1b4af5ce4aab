"""Typed configuration of the pipeline, loadable from YAML so that a run is reproducible from a file.

Load with :func:`load_config` (``akc-drake run --config FILE.yaml``); every field has the paper's default.
Unknown keys and wrong types are reported with the file name and the field.

Example ``mocap.yaml``::

    motion: II
    cycles: 2
    filter: EKF
    corrector: AKC
    weights: Wb
    camera: {width: 640, height: 480, rate_hz: 10.0, distance_m: 1.8}
"""

# No "from __future__ import annotations": pydrake.common.yaml reads the real annotation types.

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from akc_drake.errors import UserError
from akc_drake.option_maps import read_option_map

FILTERS = ("none", "KF", "EKF")
CORRECTORS = ("none", "AKC", "AKC+", "COIK")
WEIGHT_NAMES = ("Wa", "Wb", "Wc")
#: The teleop diagram's default innovation gate (standard deviations). On the clean rendered Motions I and II
#: it rejects no measurement of an arm joint (tests/test_faults_garbage.py checks the accuracy is unchanged);
#: a detector jump, a swapped side or a 0 / 65 m depth is tens of standard deviations away. On real motion it
#: rejects fast arm movements, but for the speed floor below.
TELEOP_GATE_SIGMA = 5.0
#: The speed under which the gate never rejects (``KFConfig.gate_speed_m_s``): an innovation within 6 m/s times
#: the time since the axis was last measured passes whatever the filter's covariance says. That covariance models
#: the paper's slow motions; real arms accelerate far more, and the 5-sigma gate alone rejected them: on the 10
#: real motion-capture clips with this diagram's filter settings, the paper's AKC(KF) went from 4.28 to 14.72 cm
#: mean 3D arm RMSE (simulated detector; MediaPipe on the skinned body 8.62 -> 16.47). With this floor: 4.34 and
#: 7.44 (the gate still drops MediaPipe's jumps). 4 m/s cost more on the simulated detector (KF 4.52 -> 5.18 cm
#: against 4.56), 8 m/s let more of MediaPipe's jumps through (its rig KF 9.80 -> 10.55): docs/results.md,
#: "The teleop filter's gate on real motion".
TELEOP_GATE_SPEED_M_S = 6.0
#: The teleop diagram's default longest extrapolation of an unmeasured landmark (seconds): it bridges a few
#: missed frames, but an arm moving at 1 m/s when the person leaves drags the robot target by at most 30 cm
#: before the robot holds (1 s, the mocap default, would be a metre).
TELEOP_MAX_PREDICT_S = 0.3


@dataclass
class CameraConfig:
    """The simulated RGB-D camera (D435-like at 640x480)."""

    width: int = 640
    height: int = 480
    #: Horizontal field of view, degrees (a D435 colour stream at 640x480 has fx ~ 615 px, i.e. ~55 deg).
    fov_x_deg: float = 54.97
    rate_hz: float = 10.0
    #: Distance from the operator's pelvis to the camera along the operator's forward axis, metres.
    distance_m: float = 2.0
    #: Camera height above the operator's pelvis, metres (chest height).
    height_m: float = 0.45
    #: Camera offset toward the operator's left, metres (negative: the right); it still faces the operator.
    lateral_m: float = 0.0
    #: The height above the pelvis of the point on the operator's vertical axis the optical axis passes through
    #: (None: the camera's own height, level). ``evaluate --camera`` takes the same four fields.
    aim_height_m: float | None = None
    #: Stereo model: baseline (m) and sub-pixel disparity noise (px); sigma_z = z^2 sigma_d / (f b).
    baseline_m: float = 0.05
    disparity_noise_px: float = 0.08
    #: The disparity noise's correlation length in pixels (0: independent per pixel, which the depth lookup's
    #: window averages away; :class:`~akc_drake.core.depth_noise.StereoDepthNoise`).
    noise_correlation_px: float = 0.0
    #: Render the colour image even when the detector does not need it (the simulated detector uses depth).
    render_color: bool = False

    def depth_noise(self):
        """The :class:`~akc_drake.core.depth_noise.StereoDepthNoise` of this camera."""
        from akc_drake.core.depth_noise import StereoDepthNoise

        return StereoDepthNoise(baseline_m=float(self.baseline_m), sigma_disparity_px=float(self.disparity_noise_px),
                                correlation_px=float(self.noise_correlation_px))

    def intrinsics(self):
        """The :class:`~akc_drake.core.camera.CameraIntrinsics` of this camera (pinhole, centred)."""
        import math

        from akc_drake.core.camera import CameraIntrinsics

        f = 0.5 * self.width / math.tan(math.radians(self.fov_x_deg) / 2.0)
        return CameraIntrinsics(width=int(self.width), height=int(self.height), fx=f, fy=f,
                                cx=(self.width - 1) / 2.0, cy=(self.height - 1) / 2.0, rate_hz=float(self.rate_hz))


@dataclass
class ArmLimitsConfig:
    """Each arm's command limits beyond the model file's positions and speeds, for the teleop diagram's
    :class:`~akc_drake.robot.joint_motion_limiter.JointMotionLimiter` (between the differential IK and the robot).

    The defaults are :func:`~akc_drake.robot.model.arm_motion_limits` (of the order a collaborative arm accepts;
    PAL publishes none for the TIAGo Pro): give your arm's own. Example ``teleop.yaml``::

        arm_limits: {acceleration: [10, 10, 10, 10, 15, 15, 15], jerk: [5000]}

    Attributes:
        enabled: the command goes through the limiter; false: the IK's command goes to the robot as it is.
        acceleration: rad/s^2 of joints 1-7 (both arms): empty for the model's, one number for every joint, or 7.
        jerk: rad/s^3, likewise.
    """

    enabled: bool = True
    acceleration: list[float] = field(default_factory=list)
    jerk: list[float] = field(default_factory=list)

    def validate(self, where: str = "config.arm_limits") -> "ArmLimitsConfig":
        """Check the values (positive numbers); raises ``UserError`` naming ``where`` and the field. Their count
        is checked against the arm's joints by :meth:`resolve`."""
        for name in ("acceleration", "jerk"):
            values = list(getattr(self, name))
            if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
                       for v in values):
                raise UserError(f"{where}: {name} must hold positive numbers, got {values}")
        return self

    def resolve(self, acceleration, jerk, where: str = "config.arm_limits"):
        """What the diagram passes on as ``motion_limits``: False when not enabled, else ``(acceleration, jerk)``,
        lists as long as the defaults given (the model's, one per joint), which a field left empty takes; one
        number is every joint's.

        Raises:
            UserError: a field with another count of numbers, or not positive numbers.
        """
        self.validate(where)
        if not self.enabled:
            return False

        def full(name, default):
            n = len(default)
            values = [float(v) for v in getattr(self, name)] or [float(v) for v in default]
            if len(values) not in (1, n):
                raise UserError(f"{where}: {name} must be empty (the model's), one number or {n} (joints 1-{n}), "
                                f"got {len(values)}")
            return values * n if len(values) == 1 else values

        return full("acceleration", acceleration), full("jerk", jerk)


@dataclass
class PipelineConfig:
    """What ``build_mocap_diagram`` / ``build_teleop_diagram`` build.

    Attributes:
        source: ``sim`` (rendered operator) or ``recording:DIR`` / ``bag:FILE`` / ``realsense`` / ``video:FILE``.
        motion: for ``sim``: ``I``, ``II``, ``tpose``, ``lpose`` or a BVH/AMC file path.
        skeleton: the ASF file for an AMC motion.
        joint_names: the motion file's joint-name map (role -> joint, e.g. ``{"left_shoulder": "upper_arm.L"}``;
            :func:`~akc_drake.operator.retarget.find_arm_joints`); empty: the names it finds.
        cycles: motion cycles (6 s each).
        seed: seed of the motion variation, detector and depth noise.
        camera: the simulated camera.
        filter: ``none`` | ``KF`` | ``EKF``.
        corrector: ``none`` | ``AKC`` (the paper's) | ``AKC+`` (ours: keeps seen depths) | ``COIK``.
        weights: AKC weight preset ``Wa`` | ``Wb`` | ``Wc`` (paper §III-E; default Wb).
        dims: body dimensions in metres (keys LUA LLA RUA RLA SW); empty = the simulated operator's true dimensions.
        coik_solver: ``snopt`` | ``ipopt`` | ``nlopt``.
        visibility_threshold, proximity: the occlusion filter (paper §II-C).
        stage_offset_s: the per-stage processing delay (see ``akc_drake.systems.timing``).
        gate_sigma: the filter's innovation gate in standard deviations (a measured axis further than this
            from the prediction is treated as missing for that frame; see ``akc_drake.core.kalman``).
            0 turns it off; a negative value (the default) means the diagram's own default: off in the mocap
            diagram (the paper's filter), :data:`TELEOP_GATE_SIGMA` in the teleop diagram.
        gate_speed_m_s: with the gate on, an innovation within this speed times the time since the axis was last
            measured is never rejected (``KFConfig.gate_speed_m_s``). 0 turns the floor off; a negative value
            (the default) means :data:`TELEOP_GATE_SPEED_M_S`.
        max_predict_s: how long the filter extrapolates a landmark that is no longer measured before it
            holds it and reports it LOST (then it reads NaN and the robot holds). A negative value (the
            default) means the diagram's own default: 1 s in the mocap diagram (``KFConfig``'s),
            :data:`TELEOP_MAX_PREDICT_S` in the teleop diagram, where an extrapolated wrist drives the robot.
        body: the simulated operator, ``primitive`` (fast) or ``skinned`` (MakeHuman body, what MediaPipe sees).
        detector: the 2D detector on simulated renders, ``sim`` or ``mediapipe``.
        depth_rule: how the extractor reads a landmark's depth from its pixel's window: ``nearest`` (the nearest
            surface covering a quarter of the window: a landmark on the body's edge reads the body, not the
            background) or ``median`` (:func:`~akc_drake.core.camera.depth_lookup`).
        depth_window_px: that window's size (odd, pixels); 0 (the default): scaled with the camera's focal length,
            15 pixels at 615 (640x480), about 5 cm at 2 m
            (:func:`~akc_drake.core.landmark_extraction.default_depth_window`).
        akc_plus: AKC+ settings, field -> number (:class:`~akc_drake.core.akc_plus_config.AKCPlusConfig`; e.g.
            ``{gate_sigma: 2.5}``); empty: the defaults. ``constrained_filter`` (1 or 0) is otherwise set from
            ``filter``. Used only with ``corrector: AKC+``.
        arm_limits: the robot arms' acceleration and jerk limits (:class:`ArmLimitsConfig`; teleop diagram).
    """

    source: str = "sim"
    motion: str = "II"
    skeleton: str = ""
    joint_names: dict[str, str] = field(default_factory=dict)
    cycles: int = 1
    seed: int = 0
    camera: CameraConfig = field(default_factory=CameraConfig)
    filter: str = "KF"
    corrector: str = "AKC"
    weights: str = "Wb"
    dims: dict[str, float] = field(default_factory=dict)
    coik_solver: str = "snopt"
    visibility_threshold: float = 0.7
    proximity: float = 0.05
    stage_offset_s: float = 1e-3
    gate_sigma: float = -1.0
    gate_speed_m_s: float = -1.0
    max_predict_s: float = -1.0
    body: str = "primitive"
    detector: str = "sim"
    depth_rule: str = "nearest"
    depth_window_px: int = 0
    akc_plus: dict[str, float] = field(default_factory=dict)
    arm_limits: ArmLimitsConfig = field(default_factory=ArmLimitsConfig)

    def resolved_gate_sigma(self, teleop: bool) -> float | None:
        """The gate the filter gets (None = off): ``gate_sigma`` resolved for the mocap or teleop diagram."""
        g = float(self.gate_sigma)
        if g < 0.0:
            return TELEOP_GATE_SIGMA if teleop else None
        return g if g > 0.0 else None

    def resolved_gate_speed_m_s(self) -> float | None:
        """The gate's speed floor (None = none): ``gate_speed_m_s`` resolved; only a gated filter uses it."""
        v = float(self.gate_speed_m_s)
        if v < 0.0:
            return TELEOP_GATE_SPEED_M_S
        return v if v > 0.0 else None

    def resolved_max_predict_s(self, teleop: bool) -> float | None:
        """The filter's ``max_predict_s`` (None = the filter's default) for the mocap or teleop diagram."""
        m = float(self.max_predict_s)
        if m < 0.0:
            return TELEOP_MAX_PREDICT_S if teleop else None
        return m

    def filter_settings(self, teleop: bool) -> dict:
        """The KF's or EKF's settings (``KFConfig`` fields) in the mocap or teleop diagram: the resolved gate (on
        whole landmarks, with its speed floor, when it is on) and, unless the filter's default, ``max_predict_s``."""
        gate = self.resolved_gate_sigma(teleop)
        # (A gated diagram rejects a landmark's whole measurement when one axis is an outlier.)
        out = {"gate_sigma": gate, "gate_whole_landmark": gate is not None,
               "gate_speed_m_s": self.resolved_gate_speed_m_s() if gate is not None else None}
        max_predict_s = self.resolved_max_predict_s(teleop)
        if max_predict_s is not None:
            out["max_predict_s"] = max_predict_s
        return out

    def validate(self) -> "PipelineConfig":
        """Check the choices; raises ``UserError`` naming the field."""
        if self.filter not in FILTERS:
            raise UserError(f"config.filter must be one of {', '.join(FILTERS)}, got {self.filter!r}")
        if self.corrector not in CORRECTORS:
            raise UserError(f"config.corrector must be one of {', '.join(CORRECTORS)}, got {self.corrector!r}")
        if self.weights not in WEIGHT_NAMES:
            raise UserError(f"config.weights must be one of {', '.join(WEIGHT_NAMES)}, got {self.weights!r}")
        if self.cycles < 1:
            raise UserError(f"config.cycles must be at least 1, got {self.cycles}")
        if self.body not in ("primitive", "skinned"):
            raise UserError(f"config.body must be primitive or skinned, got {self.body!r}")
        if self.detector not in ("sim", "mediapipe"):
            raise UserError(f"config.detector must be sim or mediapipe, got {self.detector!r}")
        from akc_drake.core.camera import DEPTH_RULES

        if self.depth_rule not in DEPTH_RULES:
            raise UserError(f"config.depth_rule must be one of {', '.join(DEPTH_RULES)}, got {self.depth_rule!r}")
        w = self.depth_window_px
        if isinstance(w, bool) or not isinstance(w, int) or w < 0 or (w > 0 and w % 2 == 0):
            raise UserError(f"config.depth_window_px must be 0 (scaled with the focal length) or a positive odd "
                            f"integer, got {w!r}")
        if not 0.0 <= self.visibility_threshold <= 1.0:
            raise UserError(f"config.visibility_threshold must be in [0, 1], got {self.visibility_threshold}")
        if not 0.0 <= self.proximity < 1.0:
            raise UserError(f"config.proximity must be in [0, 1), got {self.proximity}")
        if not math.isfinite(self.gate_sigma):
            raise UserError(f"config.gate_sigma must be a number (0 off, < 0 default), got {self.gate_sigma}")
        if not math.isfinite(self.gate_speed_m_s):
            raise UserError(f"config.gate_speed_m_s must be a number (0 off, < 0 default), got {self.gate_speed_m_s}")
        if not (math.isfinite(self.max_predict_s) and self.max_predict_s != 0.0):
            raise UserError(
                f"config.max_predict_s must be seconds > 0 (< 0 default), got {self.max_predict_s}"
            )
        if self.camera.rate_hz <= 0 or self.camera.width <= 0 or self.camera.height <= 0:
            raise UserError("config.camera: width, height and rate_hz must be positive")
        cam = self.camera
        place = [cam.distance_m, cam.height_m, cam.lateral_m] + ([] if cam.aim_height_m is None else [cam.aim_height_m])
        if not all(math.isfinite(float(v)) for v in place) or not cam.distance_m > 0.3:
            raise UserError("config.camera: distance_m (more than 0.3 m), height_m, lateral_m and aim_height_m must be "
                            f"finite metres, got {cam.distance_m}, {cam.height_m}, {cam.lateral_m}, {cam.aim_height_m}")
        self.arm_limits.validate()
        if self.akc_plus:
            from akc_drake.core.akc_plus_config import akc_plus_config

            try:
                akc_plus_config(dict(self.akc_plus))
            except ValueError as e:
                raise UserError(f"config.akc_plus: {e}") from None
        if self.dims:
            from akc_drake.core.skeleton import BodyDimensions

            try:
                BodyDimensions.from_dict(dict(self.dims), where="config.dims")
            except ValueError as e:
                raise UserError(str(e)) from None
        return self


def _switch_or_number(option: str, name: str, text: str):
    """An inline ``name=text`` value of ``option``: True / False for true / false (any case), else a float;
    UserError naming ``option`` for anything else."""
    switch = {"true": True, "false": False}.get(text.lower())
    if switch is not None:
        return switch
    try:
        return float(text)
    except ValueError:
        raise UserError(f"{option}: {name}={text!r} is not a number (nor true / false)") from None


def _check_fields(found: dict, known, option: str, alternative: str) -> None:
    """Refuse a command-line map's fields outside ``known``: one UserError naming ``option``, the unknown fields,
    the known ones and the option's word form (``alternative``: ``default``, ``teleop``, ``off``)."""
    unknown = sorted(set(found) - set(known))
    if unknown:
        raise UserError(f"{option}: unknown field(s) {', '.join(unknown)} (known: {', '.join(known)}; "
                        f"or {alternative})")


def parse_akc_plus(text: str, option: str = "--akc-plus") -> dict:
    """AKC+ settings (field -> value, :class:`~akc_drake.core.akc_plus_config.AKCPlusConfig`) from the command
    line: ``field=value[,field=value...]`` inline, or a JSON file holding an object
    (:func:`~akc_drake.option_maps.read_option_map`).
    Numbers; the switch ``constrained_filter`` takes true / false (or 1 / 0).

    Raises:
        UserError: as :func:`~akc_drake.option_maps.read_option_map`, or an inline value that is not a number,
            an unknown field (the known ones listed) or a value the config rejects, each naming ``option``.
    """
    from akc_drake.core.akc_plus_config import akc_plus_config

    settings = read_option_map(text, option, "field=value", "gate_sigma=2.5", "setting -> value",
                               lambda name, text: _switch_or_number(option, name, text))
    try:
        akc_plus_config(settings)
    except (ValueError, TypeError) as e:
        raise UserError(f"{option}: {e}") from None
    return settings


#: ``--filter-settings teleop``: the filter settings the teleop diagram runs by default
#: (:meth:`PipelineConfig.filter_settings`, which ``AddMocapPipeline`` builds its filter from).
TELEOP_FILTER_SETTINGS = PipelineConfig().filter_settings(teleop=True)
_FILTER_FIELDS = ("sigma_x", "sigma_y", "sigma_z", "accel_psd", "init_vel_var", "max_predict_s", "gate_sigma",
                  "gate_max_rejects", "gate_whole_landmark", "gate_speed_m_s")


def parse_filter_settings(text: str, option: str = "--filter-settings") -> dict:
    """The landmark filters' settings (field -> value of :class:`~akc_drake.core.kalman.KFConfig`, for the KF and
    the EKF alike) from the command line: ``teleop`` (:data:`TELEOP_FILTER_SETTINGS`, the teleop diagram's gate
    and prediction), ``field=value[,field=value...]`` inline, the two together (``teleop,gate_speed_m_s=0``: a
    later field wins) or a JSON file holding an object. Numbers; ``gate_whole_landmark`` takes true / false;
    ``max_predict_s`` takes inf (the paper's filter, which never holds); 0 for ``gate_sigma`` or
    ``gate_speed_m_s`` turns it off.

    Raises:
        UserError: as :func:`~akc_drake.option_maps.read_option_map`, an unknown field (the known ones listed) or
            a value the filters' configs reject, each naming ``option``.
    """
    from akc_drake.core.kalman import EKFConfig, KFConfig

    items = [t.strip() for t in str(text).split(",")]
    settings = {}
    if items and items[0].lower() == "teleop":
        settings.update(TELEOP_FILTER_SETTINGS)
        items = items[1:]
    rest = ",".join(items)
    if rest.strip() or not settings:
        settings.update(read_option_map(rest, option, "field=value", "gate_sigma=5,gate_speed_m_s=6",
                                        "setting -> value", lambda name, text: _switch_or_number(option, name, text)))
    _check_fields(settings, _FILTER_FIELDS, option, "teleop")
    for name in ("gate_sigma", "gate_speed_m_s"):
        if settings.get(name) == 0:
            settings[name] = None
    n = settings.get("gate_max_rejects")
    if isinstance(n, float) and n.is_integer():
        settings["gate_max_rejects"] = int(n)
    try:
        KFConfig(**settings)
        EKFConfig(**settings)
    except (ValueError, TypeError) as e:
        raise UserError(f"{option}: {e}") from None
    return settings


#: ``--camera`` fields, metres, in the operator's pelvis frame O (x forward, y left, z up): the camera's distance in
#: front, height above the pelvis and offset to the operator's left, and the height above the pelvis of the point
#: on the operator's vertical axis (through the pelvis) its optical axis passes through: the camera faces the
#: operator, level when ``aim_height_m`` is absent (None: at the camera's own height).
CAMERA_FIELDS = ("distance_m", "height_m", "lateral_m", "aim_height_m")
#: The evaluation's camera (and :class:`CameraConfig`'s): 2 m in front at chest height, level, facing the operator.
DEFAULT_CAMERA = {"distance_m": CameraConfig.distance_m, "height_m": CameraConfig.height_m,
                  "lateral_m": CameraConfig.lateral_m, "aim_height_m": CameraConfig.aim_height_m}


def parse_camera(text: str, option: str = "--camera") -> dict | str:
    """The simulated camera's placement from the command line: ``default``, ``field=value[,field=value...]`` inline
    (:data:`CAMERA_FIELDS`; a field left out is the default camera's, :data:`DEFAULT_CAMERA`) or a JSON file holding
    an object with those fields.

    Returns:
        ``"default"`` for the default camera (however it was spelt), else every field of :data:`CAMERA_FIELDS`
        (``aim_height_m`` None: level), the form a render spec keys renders by.

    Raises:
        UserError: as :func:`~akc_drake.option_maps.read_option_map`, an unknown field (the known ones listed), a
            value that is not a finite number, or a camera 0.3 m or less in front of the pelvis, each naming
            ``option``.
    """
    if str(text).strip().lower() == "default":
        return "default"

    def number(name, value):
        try:
            return float(value)
        except ValueError:
            raise UserError(f"{option}: {name}={value!r} is not a number (metres)") from None

    found = read_option_map(text, option, "field=value", "distance_m=3,height_m=1,aim_height_m=0.45",
                            "field -> metres", number)
    _check_fields(found, CAMERA_FIELDS, option, "default")
    camera = dict(DEFAULT_CAMERA)
    for name, value in found.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise UserError(f"{option}: {name} must be a finite number of metres, got {value!r}")
        camera[name] = float(value)
    if not camera["distance_m"] > 0.3:
        raise UserError(f"{option}: distance_m must be more than 0.3 m (in front of the operator), "
                        f"got {camera['distance_m']:g}")
    if camera["aim_height_m"] is not None and camera["aim_height_m"] == camera["height_m"]:
        camera["aim_height_m"] = None  # (aimed level: the same camera)
    return "default" if camera == DEFAULT_CAMERA else camera


#: ``--depth-noise`` fields: :class:`~akc_drake.core.depth_noise.StereoDepthNoise`'s.
DEPTH_NOISE_FIELDS = ("sigma_disparity_px", "correlation_px", "baseline_m", "edge_width_px", "edge_disparity_px",
                      "min_depth_m", "max_depth_m")


def parse_depth_noise(text: str, option: str = "--depth-noise") -> dict | str:
    """The simulated camera's depth error model from the command line: ``default``, ``field=value[,...]`` inline
    (:data:`DEPTH_NOISE_FIELDS`; a field left out is the default model's) or a JSON file holding an object with
    those fields.

    Returns:
        ``"default"`` for the default model (however it was spelt), else the fields given that differ from the
        default's (the form a render spec keys renders by); :func:`depth_noise_model` makes the model.

    Raises:
        UserError: as :func:`~akc_drake.option_maps.read_option_map`, an unknown field (the known ones listed) or
            a value the model refuses, each naming ``option``.
    """
    if str(text).strip().lower() == "default":
        return "default"

    def number(name, value):
        try:
            return int(value) if name == "edge_width_px" else float(value)
        except ValueError:
            raise UserError(f"{option}: {name}={value!r} is not a number") from None

    found = read_option_map(text, option, "field=value", "sigma_disparity_px=0.16,correlation_px=4",
                            "field -> number", number)
    _check_fields(found, DEPTH_NOISE_FIELDS, option, "default")
    try:
        model = depth_noise_model(found)
    except (TypeError, ValueError) as e:
        raise UserError(f"{option}: {e}") from None
    from akc_drake.core.depth_noise import StereoDepthNoise

    base = StereoDepthNoise()
    changed = {k: getattr(model, k) for k in DEPTH_NOISE_FIELDS if getattr(model, k) != getattr(base, k)}
    return changed or "default"


def depth_noise_model(noise):
    """The :class:`~akc_drake.core.depth_noise.StereoDepthNoise` of :func:`parse_depth_noise`'s result
    (``"default"``/None: the default model).

    Raises:
        ValueError: an unknown field or a value the model refuses.
    """
    from akc_drake.core.depth_noise import StereoDepthNoise

    if noise in (None, "default"):
        return StereoDepthNoise()
    if not isinstance(noise, dict):
        raise ValueError(f"depth noise: expected 'default' or a map of fields, got {noise!r}")
    unknown = sorted(set(noise) - set(DEPTH_NOISE_FIELDS))
    if unknown:
        raise ValueError(f"depth noise: unknown field(s) {', '.join(unknown)}")
    return StereoDepthNoise(**noise)


def describe_depth_noise(noise) -> str:
    """A depth error model (:func:`parse_depth_noise`'s result) in words for the tables' titles: ``default depth
    noise`` or its changed fields, e.g. ``depth noise sigma_disparity_px=0.16, correlation_px=4``."""
    if noise in (None, "default"):
        return "default depth noise"
    return "depth noise " + ", ".join(f"{k}={v:g}" for k, v in noise.items())


def describe_camera(camera) -> str:
    """A camera placement (:func:`parse_camera`'s result) in words, for the tables' titles: ``default camera`` or
    e.g. ``camera 3 m in front, 1 m above the pelvis, 0.8 m to the left, aimed 0.45 m above the pelvis``."""
    if camera in (None, "default"):
        return "default camera"
    words = [f"camera {camera['distance_m']:g} m in front", f"{camera['height_m']:g} m above the pelvis"]
    lateral = float(camera.get("lateral_m", 0.0))
    if lateral:
        words.append(f"{abs(lateral):g} m to the {'left' if lateral > 0 else 'right'}")
    aim = camera.get("aim_height_m")
    words.append("level" if aim is None else f"aimed {aim:g} m above the pelvis")
    return ", ".join(words)


def parse_arm_limits(text: str, option: str = "--arm-limits") -> ArmLimitsConfig:
    """The arms' acceleration and jerk limits (:class:`ArmLimitsConfig`) from the command line: ``off`` (no
    limiter), ``acceleration=A,jerk=J`` inline (rad/s^2, rad/s^3; one number for every joint, a field left out
    is the model's) or a JSON file holding an object with those fields (``enabled``, and a number or 7 numbers
    each).

    Raises:
        UserError: as :func:`~akc_drake.option_maps.read_option_map`, an unknown field (the known ones listed) or
            a value that is not a positive number, each naming ``option``.
    """
    if str(text).strip().lower() == "off":
        return ArmLimitsConfig(enabled=False)
    fields = ("enabled", "acceleration", "jerk")
    found = read_option_map(text, option, "field=value", "acceleration=10,jerk=5000", "field -> value",
                            lambda name, text: _switch_or_number(option, name, text))
    _check_fields(found, fields, option, "off")
    enabled = found.get("enabled", True)
    if not isinstance(enabled, bool):
        raise UserError(f"{option}: enabled must be true or false, got {enabled!r}")
    limits = {}
    for name in ("acceleration", "jerk"):
        v = found.get(name, [])
        limits[name] = list(v) if isinstance(v, list) else [v]
    return ArmLimitsConfig(enabled=enabled, **limits).validate(option)


def load_config(path: str | Path, schema=PipelineConfig):
    """Load a YAML config file into ``schema`` (a dataclass), with clear errors.

    Raises:
        UserError: the file is missing, not YAML, has an unknown key or a value of the wrong type.
    """
    from pydrake.common.yaml import yaml_load_typed

    p = Path(path)
    if not p.is_file():
        raise UserError(f"{p}: config file not found")
    try:
        cfg = yaml_load_typed(schema=schema, filename=str(p))
    except (RuntimeError, ValueError, TypeError) as e:
        where = _locate_yaml_error(p, schema)
        raise UserError(f"{p}: {where or _one_line(e)}") from None
    except Exception as e:  # yaml.YAMLError and friends
        raise UserError(f"{p}: not a valid YAML config ({_yaml_problem(e)})") from None
    if hasattr(cfg, "validate"):
        try:
            cfg.validate()
        except UserError as e:
            raise UserError(f"{p}: {e}") from None
    return cfg


def _one_line(e) -> str:
    return " ".join(str(e).split())


def _yaml_problem(e) -> str:
    """A YAML parser error as one line: ``line L, column C: problem``."""
    mark = getattr(e, "problem_mark", None)
    problem = getattr(e, "problem", None)
    if mark is not None and problem:
        return f"line {mark.line + 1}, column {mark.column + 1}: {_one_line(problem)}"
    return f"{type(e).__name__}: {_one_line(e)}"


def _locate_yaml_error(path: Path, schema) -> str | None:
    """Which key of the YAML file ``schema`` rejects: ``line N: field a.b: reason`` (None if not found).

    Drake's typed loader names neither the line nor (for a bad value) the field; this re-checks the file one
    key at a time, descending into nested dataclass fields.
    """
    import typing

    import yaml
    from pydrake.common.yaml import yaml_load_typed

    try:
        root = yaml.compose(path.read_text(encoding="utf-8"))
    except Exception:
        return None

    def check(node, cls, prefix: str) -> str | None:
        if not isinstance(node, yaml.MappingNode) or not dataclasses.is_dataclass(cls):
            return None
        hints = typing.get_type_hints(cls)
        names = [f.name for f in dataclasses.fields(cls)]
        for key_node, value_node in node.value:
            key = str(key_node.value)
            line = key_node.start_mark.line + 1
            if key not in names:
                return f"line {line}: unknown key '{prefix}{key}' (known: {', '.join(names)})"
            one = yaml.serialize(yaml.MappingNode("tag:yaml.org,2002:map", [(key_node, value_node)]))
            try:
                yaml_load_typed(schema=cls, data=one)
            except Exception as e:
                inner = check(value_node, hints.get(key), f"{prefix}{key}.")
                if inner is not None:
                    return inner
                scalar = isinstance(value_node, yaml.ScalarNode)
                shown = value_node.value if scalar else "(not a single value)"
                return f"line {line}: field {prefix}{key} = {shown!r}: {_one_line(e)}"
        return None

    return check(root, schema, "")


def dump_config(cfg) -> str:
    """The config as YAML text (what ``load_config`` reads back)."""
    from pydrake.common.yaml import yaml_dump_typed

    return yaml_dump_typed(cfg)


def replace(cfg, **changes):
    """A copy of ``cfg`` with ``changes`` (dataclasses.replace, re-validated)."""
    out = dataclasses.replace(cfg, **changes)
    return out.validate() if hasattr(out, "validate") else out
