"""Settings of AKC+ (:mod:`akc_drake.core.akc_plus`), in their own module to keep the corrector's short."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

#: The settings that are switches (True, False or None: resolved by :func:`akc_plus_config`); the rest are numbers.
SWITCHES = ("constrained_filter", "seen_wrist_anchor", "seen_depth_fusion")
#: The hand rule's length (``hand_length_m``) over the arm's calibrated forearm: 8.5 cm, MediaPipe's knuckles on
#: the rendered adult (8-8.5 cm; the skinned body's 8.6-9.4), over its 27.5 cm forearm. As a share, it follows the
#: operator's size: with a constant 8.5 cm the simulated detector on an operator 1.2 times as large (hand 10.8 cm)
#: missed the per-axis target by +1.19 / +1.33 cm on the 10 clips, the wrists' seen frames; 10.2 cm met it.
HAND_TO_FOREARM = 0.085 / 0.275


@dataclass(frozen=True)
class AKCPlusConfig:
    """Settings of AKC+ (see the module docstring). Lengths in metres.

    Settings "per frame" or "between two frames" (and the running means' weights of the newest frame, and the
    frame counts) are stated at the paper's camera rate, 10 Hz (:data:`REFERENCE_PERIOD_S`); a corrector at
    another rate scales them to its frame period so that they mean the same in seconds (:func:`per_frame`).

    ``consistency_m``, ``jump_m``, ``gate_frames``, ``sigma_filter_m`` and ``drift_m_per_frame`` serve only
    without the filter's covariance; ``depth_sigma_m``, ``image_sigma_m``, ``length_sigma_m``, ``gate_sigma``,
    ``nis_alpha`` and ``nis_floor`` only with it.

    Attributes:
        consistency_m: a measured depth farther than this from the filtered one is not trusted.
        length_tol_m: a measured joint whose segment length (to the wrist, or to a trusted elbow) is off the
            calibrated one by more than this is not trusted.
        sigma_filter_m: the filter's depth standard deviation for a joint whose depth was just lost.
        drift_m_per_frame: added to it per frame without a trusted depth (extrapolation drift).
        sigma_temporal_m: how far a joint may move between two frames (10 Hz: 1 m/s -> 0.1 m).
        sigma_width_m: standard deviation of the shoulder-width term (0 turns it off).
        sigma_torso_m: standard deviation of a shoulder's depth about the hips' (torso lean; 0 turns it off).
        sigma_shoulder_m: how far a shoulder may move relative to the hips between two frames, per axis (a torso
            turning at 0.1 m/s at the shoulder): the random walk of a shoulder whose depth the occlusion
            filter dropped (or that the detector lost altogether: then x, y too), held at its seen offset from the
            hips' centre, learnt in frames with both hips' depths measured (with the covariance; 0 turns it off,
            and with it every torso rule: the other shoulder's hold, the torso's outvotes, the jump against the
            other shoulder, whose held depth difference walks by the same amount).
        shoulder_alpha: weight of the newest frame in the running means of that offset and of the shoulders' depth
            difference (0.2: a time constant of 5 frames, as ``nis_alpha``): the depths read in the last frames
            before an occlusion are partly the occluder's (the bench's Motion I: 3-7 cm in front over the 2-3
            frames before the forearm covers the shoulder; held at the last one, the shoulder's z RMSE was 3.3 cm
            against 2.15 without the hold).
        temporal_cap: the temporal term is capped at this many standard deviations (squared): continuity breaks
            ties and resists single-frame evidence, but persistent evidence (filter, torso) can undo a wrong
            configuration instead of locking it in.
        elbow_min_deg: candidates folded more than this (or hyperextended) are penalised.
        xy_tol_m: a seen shoulder that would move the elbow's image position (x, y) by more than this makes
            the elbow be placed from the shoulder and the wrist follow.
        jump_m: a seen depth farther than this from the joint's last output is not trusted (an occluder's,
            e.g. the elbow's surface read at the shoulder's pixel) ...
        gate_frames: ... unless it has been so for this many frames and fits the arm's lengths.
        occlusion_radius_m: a shoulder this close (x, y, metres) to its elbow does not count as seen (its
            depth may be the upper arm's surface; 8 cm ~ 25 px at 2 m). This rule and the next act only on an
            elbow detected this frame: a lost elbow's position is a guess (MediaPipe's boxing clip driven by
            the rig at 30 Hz: an elbow held 54 cm in front of its shoulder unseated a shoulder read within 1 cm,
            which was then rebuilt from the lost joints 47 cm in front).
        arm_radius_m: the upper arm's radius (a 30 cm circumference). An upper arm pointing towards the camera at
            angle theta from the line of sight covers its shoulder's pixel: the depth read there is the arm's
            surface, ``r / sin(theta)`` in front of the joint where one facing the camera reads ``r`` (which the
            depth offset removes). A shoulder whose excess bias, ``r (l_u / d_xy - 1)`` with ``d_xy`` the elbow's
            distance in x, y and the elbow in front, exceeds ``consistency_m`` does not count as seen (0 turns
            the rule off). With MediaPipe on the skinned body (bvhtools_a3: the arm 20 degrees off the line of
            sight) the shoulder read 6 cm in front and the kept shoulder moved the seen elbow 4-5 cm.
        forearm_radius_m: the forearm's radius near the elbow (a 25 cm circumference). A forearm pointing towards
            the camera covers its elbow's pixel as the upper arm covers its shoulder's; while the shoulder's depth
            is not read (dropped, or lost), the elbow's depth carries it through the upper arm's length, and its
            variance grows by the square of the excess ``r (l_f / d_xy - 1)``, ``d_xy`` the wrist's distance in x,
            y (:func:`~akc_drake.core.arm_geometry.covered_excess`; 0 turns the rule off). The elbow's reading on
            the evaluation's renders, by the cosine of the forearm's angle to the line of sight (0.8-0.9 /
            0.9-1.0): 2.0 / 3.8 cm in front with the simulated detector, 1.1-1.6 / 2.1-2.8 with MediaPipe. Where
            the shoulder is read too, the variance is left as it is: a softer depth there let MediaPipe's 2D errors
            into it through the lengths (every MediaPipe set worse in 3D, session 48).
        arm_cover_deg: a seen shoulder's depth is outvoted as an occluder's (two against one: a seen elbow that
            fits the wrist, and a rebuilt shoulder behind the reading) only when its own arm can cover its pixel:
            the wrist's forearm passes within ``occlusion_radius_m`` of it in the image, or the upper arm points
            within this angle of the line of sight (its image length below ``l_u sin`` of it; 90 turns the test
            off). Of 62 outvotes that moved a shoulder back (MediaPipe and simulated sets, 10 Hz, both filters),
            the 15 with neither cover all moved it away from the truth, 2-24 cm (MediaPipe's 2D upper arm short,
            its Pythagorean depth long); of the 47 with one, 45 moved it towards the truth, 1-28 cm (a shoulder
            read on its arm's surface or under its hand). The 37 degrees is read off those sets.
        depth_sigma_m, image_sigma_m: the measurement's standard deviations in depth and in x, y (the
            filter's R: ``KFConfig.sigma_z``, ``sigma_x``); without the filter's covariance they also stand
            for it.
        length_sigma_m: the calibrated lengths' standard deviation (a T-pose calibration: ``EKFConfig.sigma_c``);
            the length projections read it as each landmark's offset from its joint centre (variance
            ``length_sigma_m^2 / 2`` per axis and landmark: a segment's two ends make up the length's variance).
        gate_sigma: the statistical tests' gate in standard deviations (a measured depth against the filter,
            the arm against the calibrated lengths: chi2 at the same tail probability, 99.7 % for 3).
        nis_alpha: weight of the newest frame in the running mean of each joint's normalised innovation
            squared (0.2: a time constant of 5 frames, at any frame rate: :func:`per_frame`); the filter's
            variance times that mean is the error variance the residuals show (covariance matching): a lagging
            joint's grows, a still one's shrinks.
        nis_floor: the smallest factor the running mean may apply to the filter's variance.
        elbow_offset_alpha: weight of the newest frame in the running means from which the elbow's landmark offset
            is learnt (:func:`~akc_drake.core.akc_plus_lengths.learn_elbow_offset`; 0.05: 20 measured arms, at any
            frame rate, as ``nis_alpha``); 0 keeps every landmark's offset at ``length_sigma_m^2 / 2``. The elbow
            ends both segments: its offset from the joint lengthens one and shortens the other as far as they are
            aligned, which a shoulder's or a wrist's offset, each in one segment, does not; the two misfits'
            product measures it. MediaPipe's 2D elbow is 1.5-2 cm off the joint in y on the skinned body where its
            shoulder is 0.2 cm off, and the projections shared each upper arm's misfit equally: a seen shoulder moved
            1-2 cm (bvhtools_a1's left shoulder y over the KF +0.79 cm on its seen frames). Learnt (session 55),
            the elbow takes it: that shoulder +0.79 -> +0.12 (+0.73 -> +0.11 after the EKF); on the 18 evaluation
            sets each worst increase moved by -0.47 to +0.18 cm and each pooled 3D RMSE by -0.17 to +0.03 cm.
        hand_length_m: the wrist to its index and pinky knuckles' midpoint. A measured wrist its own hand hides
            (the forearm toward the camera) reads the hand, up to a hand's length in front: it is put that far behind
            the knuckles (:func:`~akc_drake.core.arm_geometry.behind_hand`). None (the default): the calibrated
            forearms' mean times :data:`HAND_TO_FOREARM`, so that a smaller or a taller operator's hand is theirs; a
            number: that length (0 turns the rule off).
        recent_frames: a depth not measured for up to this many frames (0.3 s at 10 Hz) whose filter variance
            is below the variance eq. 7-8 would rebuild it with counts as known: the filter's variance is a
            trustworthy error measure only shortly after a measurement (the running NIS was measured then;
            further on, unmodelled motion, or an EKF's bone constraints, which are the rebuild's own lengths,
            dominate it). After a constrained filter, a joint lost altogether for longer counts the filter's
            extrapolation as no surer than the segment held at its neighbour, and a shoulder whose depth is dropped
            for longer its filter's depth as no surer than the shoulder held on the torso
            (:func:`~akc_drake.core.akc_plus_evidence.fuse_held`'s ``honest_frames``).
        hips_lost_frames: the hips no torso reference (not measured, or a depth failing the innovation test) for
            this many frames (1 s at 10 Hz: out of the image, not a hand passing over a hip), the other shoulder,
            seen, carries a held shoulder instead.
        constrained_filter: the filter's posterior also holds bone-length constraints (our EKF, the paper's
            per-joint EKF; the evaluation and the diagrams set it from the filter): a measured coordinate whose
            running NIS exceeds 1 is fused again with its measurement at the prior variance the NIS shows
            (:func:`~akc_drake.core.akc_plus_evidence.arm_variances`). The EKF moves a seen joint off its
            measurement to fit lengths that the projection then imposes exactly in its own metric; undone in
            proportion to the evidence, AKC+(EKF)'s pooled arm z RMSE fell 0.1-0.25 cm and its lost joints' z
            0.04-0.36 cm on every set (real-motion clips and held-out windows, both detectors and protocols).
            With a plain KF the excess NIS came as much from the measurement. None (the default): set from the
            filter AKC+ follows (:func:`akc_plus_config` with ``filter_kind``; the evaluation and the diagrams do):
            on after an EKF, off after a KF; a corrector built with None treats it as off.
        seen_depth_sigma_m: after a constrained filter (``constrained_filter``), a depth measured this frame that
            passes the innovation test is taken as read, with this standard deviation, instead of the EKF's
            (0: off, the NIS refit above). The EKF moves a seen joint off its reading (its bone constraints, and a
            lag its ``R`` of ``depth_sigma_m`` allows): on the MediaPipe clips, over the frames whose reading is
            within 10 cm, the elbows' depth was read to 1.3-1.4 cm RMSE, the EKF's 2.6-2.9, AKC+(EKF)'s 2.1-2.2.
            The filters' 5 cm is a D435 pixel's error (2 % of the range) and stays the innovation tests' ``R``;
            a joint's reading (the nearest surface in a window, with the surface-to-centre offset) errs by about
            1 cm of stereo noise at 2 m and 1 cm of the offset's change with the pose. AKC+(EKF)'s pooled 3D arm
            RMSE fell on every ``ours`` set (simulated clips 2.40 -> 1.73 cm, MediaPipe clips 4.10 -> 3.65); 1 cm
            and 2 cm gave within 0.1 cm of 1.5. Off under the ``paper`` protocol (no depth offset: a reading is
            the surface's, 4-5 cm in front of the joint; taken as read, AKC+(EKF)'s worst increase on the rig
            went +0.19 -> +0.78 cm). With ``seen_depth_fusion`` it is also the reading noise assumed until
            frames have measured it, and the smallest error a seen depth is given (after a KF too). It is also the
            gate of a seen shoulder's reading against eq. 8's rebuild in front of it, which an elbow that fits the
            wrist would otherwise make (``CandidateSearch._outvoted``; the filter's ``R`` when 0).
        seen_depth_fusion: with ``seen_depth_sigma_m``, a seen depth passing the test is the reading and the
            filter's fused by the variances their residuals show, not taken as read
            (:func:`~akc_drake.core.akc_plus_evidence.arm_variances`): the reading's frame-to-frame noise (the
            arm's stillest joint's, :func:`~akc_drake.core.akc_plus_evidence.depth_reading_noise`) against the
            filter's error (the residual's running mean square, this frame's share bounded, less that noise).
            The default's simulated readings carry about 0.1 cm of stereo noise and the rule gives nearly the
            reading, as before (every set's worst within 0.05 cm of it, pooled 3D at most 0.05 cm worse). A real
            stereo camera's do not average away over the depth window (``--depth-noise
            sigma_disparity_px=0.16,correlation_px=4``: 1.3 cm per reading at 2 m); there a still joint's reading
            taken as read was worse than the EKF's average, AKC+(EKF)'s worst increase +0.61 cm (the third held-out
            set) and +0.75 (MediaPipe's clips); fused, +0.36 and +0.46, the pooled 3D arm RMSE within 0.05 cm.
            After a KF, a seen depth that covariance matching would let replace the filter's (its error variance
            above ``R``) is fused so instead, its variance the combination's in the KF's model (session 54): a
            single misread frame was taken whole; AKC+(KF)'s worst increase with the noisier camera on the second
            held-out set +0.55 -> +0.48 cm, every other set's worst within 0.02 cm and pooled 3D within 0.01.
            False: taken as read (session 46's rule; after a KF, the filter's replaced); None: on (the default, True).
        seen_wrist_anchor: a wrist measured in 3D is kept where the fit of its forearm would move its x, y beyond
            the gate: its elbow goes on the circle between the kept shoulder and the wrist, nearest the elbow's
            estimate. Without it, a kept shoulder and a seen elbow whose lengths misfit the wrist share the misfit
            with the wrist (``project_forearm``). Measured in the teleop demo's pick-and-place (MediaPipe on the
            skinned body, reaching down and towards the camera): MediaPipe's 2D elbow 13 cm below the joint, on
            the forearm, and the shoulder read on the upper arm, agree with each other; the fit moved the seen wrist
            10-15 cm in the 15 frames before every failed grasp, and the tool pushed the box away (AKC+(KF) 3 of 10
            seeds). On the real-motion sets the same rule costs a little: the MediaPipe clips' worst after the KF
            +1.31 -> +1.94 cm (mocapbank's left wrist x, whose measurement was off), every other set within 0.02
            cm. In teleoperation the wrist is the robot's command, and a measured one is the operator's hand;
            None (the default): on in the teleop diagram, off elsewhere (:func:`akc_plus_config` with ``teleop``).
    """

    consistency_m: float = 0.05
    length_tol_m: float = 0.10
    sigma_filter_m: float = 0.05
    drift_m_per_frame: float = 0.02
    sigma_temporal_m: float = 0.10
    sigma_width_m: float = 0.05
    sigma_torso_m: float = 0.20
    sigma_shoulder_m: float = 0.01
    shoulder_alpha: float = 0.2
    temporal_cap: float = 4.0
    elbow_min_deg: float = 40.0
    xy_tol_m: float = 0.03
    jump_m: float = 0.15
    occlusion_radius_m: float = 0.08
    arm_radius_m: float = 0.05
    forearm_radius_m: float = 0.04
    arm_cover_deg: float = 37.0
    gate_frames: float = 10.0
    depth_sigma_m: float = 0.05
    image_sigma_m: float = 0.01
    length_sigma_m: float = 0.01
    gate_sigma: float = 3.0
    nis_alpha: float = 0.2
    nis_floor: float = 0.01
    elbow_offset_alpha: float = 0.05
    recent_frames: float = 3.0
    hips_lost_frames: float = 10.0
    hand_length_m: float | None = None
    constrained_filter: bool | None = None
    seen_wrist_anchor: bool | None = None
    seen_depth_sigma_m: float = 0.015
    seen_depth_fusion: bool | None = True

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "hand_length_m" and v is None:  # (None: from the calibrated forearm)
                continue
            if f.name in SWITCHES:  # (the switches; every other field is a number)
                if v is not None and not isinstance(v, bool):
                    raise ValueError(f"AKCPlusConfig.{f.name} must be True, False or None, got {v!r}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"AKCPlusConfig.{f.name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        for name in ("sigma_filter_m", "sigma_temporal_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"AKCPlusConfig.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("shoulder_alpha", "nis_alpha"):  # (a running mean's weight of the newest frame)
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"AKCPlusConfig.{name} must be in (0, 1], got {getattr(self, name)!r}")
        if self.elbow_offset_alpha > 1.0:
            raise ValueError(f"AKCPlusConfig.elbow_offset_alpha must be in [0, 1], got {self.elbow_offset_alpha!r}")
        if self.arm_cover_deg > 90.0:
            raise ValueError(f"AKCPlusConfig.arm_cover_deg must be at most 90, got {self.arm_cover_deg!r}")
        if self.elbow_min_deg >= 180.0:
            raise ValueError(f"AKCPlusConfig.elbow_min_deg must be below 180, got {self.elbow_min_deg!r}")


def hand_lengths(config: AKCPlusConfig, forearms) -> tuple[float, float]:
    """Each arm's (left, right) hand length for the hand rule: ``config.hand_length_m``, or, None, the mean of the
    calibrated forearms (``forearms``) times :data:`HAND_TO_FOREARM` (one hand size: a forearm's calibration error,
    or a body's asymmetry, is not the hand's)."""
    h = config.hand_length_m
    h = HAND_TO_FOREARM * 0.5 * (forearms[0] + forearms[1]) if h is None else h
    return h, h


#: The frame period (s) at which :class:`AKCPlusConfig`'s per-frame settings are stated: 10 Hz, the paper's camera
#: rate and the evaluation's.
REFERENCE_PERIOD_S = 0.1


@dataclass(frozen=True)
class PerFrame:
    """AKC+'s rate-dependent settings for one frame period (:func:`per_frame`).

    Attributes:
        step_sigma_m: how far a joint may move between two frames (the candidates' temporal term).
        temporal_walk_var: the random walk's variance per blind frame of a held segment (forearm, upper arm).
        shoulder_walk_var: the random walk's variance per blind frame of a shoulder held on the torso.
        shoulder_alpha: the shoulders' running means' weight of the newest frame.
        nis_alpha: the running NIS's weight of the newest frame (``config.nis_alpha`` at every rate).
        recent_frames, gate_frames, hips_lost_frames: the frame counts.
        jump_m: the largest depth jump between two frames (without the covariance).
        drift_m_per_frame: the filter's drift per frame without a trusted depth (without the covariance).
    """

    step_sigma_m: float
    temporal_walk_var: float
    shoulder_walk_var: float
    shoulder_alpha: float
    nis_alpha: float
    recent_frames: float
    gate_frames: float
    hips_lost_frames: float
    jump_m: float
    drift_m_per_frame: float


def per_frame(config: AKCPlusConfig, period_s: float | None = None) -> PerFrame:
    """``config``'s rate-dependent settings at frame period ``period_s``, the same in seconds as at 10 Hz.

    With ``r = period_s / REFERENCE_PERIOD_S``: a motion between two frames (``sigma_temporal_m``, ``jump_m``,
    ``drift_m_per_frame``) scales with ``r``; a random walk's variance per frame (``sigma_temporal_m^2`` for a
    held segment, ``sigma_shoulder_m^2``) with ``r``; the shoulders' running means' weight ``a`` becomes
    ``1 - (1 - a)^r`` (the same time constant in seconds); frame counts scale with ``1 / r``. Sampled at 30 Hz with
    the 10 Hz values, AKC+(KF)'s shoulders and elbows on the bench were 0.2-0.7 cm worse in z (docs/results.md,
    "Frame rate"). ``nis_alpha`` is not scaled: the running NIS is an estimate from the innovations it averages,
    its noise set by their number, not by seconds, so a faster camera catches a lagging filter sooner at the same
    noise (the 10 clips at 30 Hz: AKC+'s mean 3D arm RMSE 2.24 -> 2.13 cm after the KF, 2.63 -> 2.51 after the EKF).

    Args:
        config: the settings.
        period_s: the corrector's frame period, seconds (None: :data:`REFERENCE_PERIOD_S`).

    Raises:
        ValueError: a period that is not a positive, finite number.
    """
    if period_s is None:
        period_s = REFERENCE_PERIOD_S
    if isinstance(period_s, bool) or not isinstance(period_s, (int, float)) or not 0.0 < period_s < math.inf:
        raise ValueError(f"AKC+ period_s must be a positive number of seconds, got {period_s!r}")
    r = period_s / REFERENCE_PERIOD_S
    if abs(r - 1.0) < 1e-9:  # (10 Hz up to rounding, e.g. a median of sampled times' steps: exactly the settings)
        r = 1.0
    return PerFrame(
        step_sigma_m=config.sigma_temporal_m * r,
        temporal_walk_var=config.sigma_temporal_m**2 * r,
        shoulder_walk_var=config.sigma_shoulder_m**2 * r,
        shoulder_alpha=_weight(config.shoulder_alpha, r),
        nis_alpha=config.nis_alpha,  # (per innovation, at any rate: see above)
        recent_frames=config.recent_frames / r,
        gate_frames=config.gate_frames / r,
        hips_lost_frames=config.hips_lost_frames / r,
        jump_m=config.jump_m * r,
        drift_m_per_frame=config.drift_m_per_frame * r,
    )


def _weight(a: float, r: float) -> float:
    """A running mean's weight ``a`` per reference frame, per frame ``r`` times as long (exactly ``a`` at ``r = 1``)."""
    return a if r == 1.0 else 1.0 - (1.0 - a) ** r


def akc_plus_config(settings=None, filter_kind: str | None = None, teleop: bool | None = None) -> AKCPlusConfig:
    """The :class:`AKCPlusConfig` of ``settings``, its ``constrained_filter`` resolved for the filter it follows and
    its ``seen_wrist_anchor`` for where it runs.

    Args:
        settings: None (the defaults), an :class:`AKCPlusConfig`, or a mapping of some of its fields (plain data:
            what a YAML config's ``akc_plus``, ``--akc-plus`` and the evaluation's workers carry).
            A switch (``constrained_filter``, ``seen_wrist_anchor``) there may also be 1 or 0 (a YAML map of
            numbers).
        filter_kind: "KF" or "EKF" (the filter AKC+ follows), or None: a ``constrained_filter`` left at None is
            then set, True after the EKF; one the settings give is kept.
        teleop: True in the teleop diagram, False elsewhere, None: left as it is. A ``seen_wrist_anchor`` left at
            None is set to it; one the settings give is kept.

    Raises:
        ValueError: an unknown field (the known ones listed) or a value :class:`AKCPlusConfig` rejects.
    """
    if settings is None:
        config = AKCPlusConfig()
    elif isinstance(settings, AKCPlusConfig):
        config = settings
    elif isinstance(settings, Mapping):
        names = [f.name for f in dataclasses.fields(AKCPlusConfig)]
        unknown = [k for k in settings if k not in names]
        if unknown:
            raise ValueError(f"unknown AKC+ setting(s) {', '.join(map(repr, unknown))}; known: {', '.join(names)}")
        kw = dict(settings)
        for name in SWITCHES:
            switch = kw.get(name)
            if not isinstance(switch, bool) and isinstance(switch, (int, float)) and switch in (0, 1):
                kw[name] = bool(switch)
        config = AKCPlusConfig(**kw)
    else:
        raise ValueError(f"AKC+ settings must be an AKCPlusConfig or a mapping of its fields, got "
                         f"{type(settings).__name__}")
    if filter_kind is not None and config.constrained_filter is None:
        config = dataclasses.replace(config, constrained_filter=filter_kind == "EKF")
    if teleop is not None and config.seen_wrist_anchor is None:
        config = dataclasses.replace(config, seen_wrist_anchor=bool(teleop))
    return config
