"""AKC+: our arm kinematic correction, which keeps what the camera sees and rebuilds only what it loses.

The paper's AKC (:mod:`akc_drake.core.akc`) replaces the elbow and shoulder depths of every frame by one of
four Pythagorean candidates, even when the camera measured those depths well; on real motion that makes
well-seen joints worse than the filter it corrects. AKC+ was designed on a design half of real motion-capture
clips (docs/results.md, "Real motion"; the other half held out) and differs from the paper as follows.

**With the filter's covariance** (``correct(pose, measured, variance)``, the filter's posterior variance of
each coordinate; the evaluation always gives it), "trustworthy" is a statistical test, not a distance in cm:

* *Seen depth*: measured this frame after the occlusion filter, and passing the innovation test: for a
  Kalman update with measurement variance ``R`` (``depth_sigma_m``) the residual ``z - fz`` has variance
  ``R - P``, so ``(z - fz)^2 / (R - P)`` is exactly the normalised innovation squared; within ``gate_sigma``.
  A shoulder within ``occlusion_radius_m`` of its elbow in the image is not seen (the pair the paper's occlusion
  filter lacks; an elbow detected this frame: a lost one's position is a guess); the filter that followed such a
  rejected depth (passes the test and moved towards it since the joint was last seen) is then no prior for it.
* *Ray test*: a measured depth the innovation test rejects is an occluder's or the filter's error. The image
  measures the joint's ray (x / z, y / z), and an occluder's depth moves the measured point along it, not off
  it: a filtered point that, scaled to the measured depth, is off the measured ray by more than the gate
  (chi2, 2 dof) is the filter's error (e.g. the paper's per-joint EKF, whose bone constraint moves a seen
  joint towards a lost neighbour), and the measured point replaces it, with the measurement's variance; so does
  a filter's depth that jumped from our last output when the measurement agrees with it (an EKF's constraint, a
  KF lagging after a wall reading), or that moved in front of it when the measurement is behind (``ray_check``).
* *Reach*: a measured point that replaced the filter's (ray test, covariance matching) farther from another
  joint measured this frame than the arm's calibrated lengths reach (chi2 of the stretch) is no reading of the
  joint (the background behind a landmark off the body's edge, 1-1.5 m deep with MediaPipe): the filter's point
  and variances come back (:func:`~akc_drake.core.akc_plus_evidence.unreachable_replacements`).
* *Covariance matching*: a running mean of each arm coordinate's NIS (each frame's winsorised at the gate,
  weight ``nis_alpha``) scales the filter's variance into the error variance its residuals show: a lagging
  filter on a fast joint gets more, a still joint less (a blind axis is never shrunk). A measured x or y that
  passes the test, of a filter whose error variance so exceeds ``R``, replaces the filter's; such a depth is fused
  with the filter's by their residuals' variances (``seen_depth_fusion``), and after an EKF (``constrained_filter``:
  its bone lengths pull a seen joint off its measurement) every depth passing the test, an x or y of running NIS
  ``k`` > 1 refitted, ``z - (z - f) / k`` (:func:`~akc_drake.core.akc_plus_evidence.arm_variances`).
* *Minimal change*: when both depths are known (seen; or not measured this frame and known by the filter as
  well as a measurement would know them or, dropped at most ``recent_frames`` ago, better than eq. 7-8 would
  rebuild them from their neighbours: :func:`~akc_drake.core.arm_geometry.rebuild_variance`, which is large
  for a segment near the image plane, plus the risk of choosing the mirror candidate under the filter's
  depth variance), and the arm passes the chi2 test against the calibrated lengths (``length_sigma_m``;
  after an EKF, whose bone constraint fitted its arm to them already, the arm as measured when measured whole:
  :func:`~akc_drake.core.akc_plus_lengths.measured_arm`), the output is the arm nearest the filter's in its
  covariance metric with the exact lengths (:func:`~akc_drake.core.akc_plus_lengths.project_arm`): the joint
  the filter is least sure of moves, mostly in depth. The metric adds each landmark's offset from its joint
  centre (isotropic, ``length_sigma_m^2 / 2`` per axis: what makes a measured segment's length differ from the
  calibrated one), so that a length mismatch of a segment near the image plane is shared with the x, y instead
  of becoming a depth error several times as large (a segment near the image plane turned 1-2 cm of length into
  5-10 cm of a seen shoulder's depth). The elbow's, which misfits both segments, is learnt from their misfits'
  product (``elbow_offset_alpha``, :func:`~akc_drake.core.akc_plus_lengths.learn_elbow_offset`): MediaPipe's 2D
  elbow off the joint moved a seen shoulder 1-2 cm. A shoulder so known is kept when the elbow is rebuilt.
* A wrist the detector lost altogether (no x, y): its prior is the filter's extrapolation times the forearm as our
  output last had it (not from a wrist misread, the odd one out of an arm measured whole; after such readings the hold
  alone, as the filter took them: :func:`~akc_drake.core.akc_plus_evidence.held_segments`), carried by this frame's
  elbow (a random walk of ``sigma_temporal_m^2`` per blind frame; :func:`~akc_drake.core.akc_plus_evidence.fuse_held`):
  a constant-velocity extrapolation runs on while the hand turns, the forearm moves with the elbow the camera still sees
  (mocapbank's left wrist, lost for 6 frames: the filter 24 cm off in x, the fusion with our last output 11.5 cm off).
  Known worse than the shoulder and the elbow, or than the shoulder and beyond the arm's reach from it (boxing,
  simulated moving torso: 1.25 m off, it moved the seen x, y 14 cm), it is no anchor (nothing measured it): the arm is
  built from the shoulder out and the wrist goes to its nearest point at the forearm's length in its own metric
  (:func:`~akc_drake.core.akc_plus_lengths.sphere_point`). Nor is a wrist whose measured depth the innovation test
  rejects and no replacement resolved (the filter and the measurement disagree, either may be wrong: with MediaPipe, a
  filter that followed a depth read past the silhouette part of the way, and the arm rebuilt from it moved the seen
  elbow and shoulder up to 1 m). A shoulder kept only for want of the wrist (its own reading rejected, not held) yields
  to a seen elbow within ``consistency_m`` of its reading: at l_u from it, x, y kept (a KF lagging 90 cm had moved the
  elbow 85 cm).
* An elbow lost altogether likewise: the filter's extrapolation times the upper arm held at this frame's shoulder,
  and a wrist lost with it moves with that elbow (MediaPipe lost bvhtools_a2's left arm for 20 frames: the filter's
  elbow ran 25 cm off in depth, and the elbow rebuilt between it and the held wrist 37 cm). After an EKF
  (``constrained_filter``), a joint lost for more than ``recent_frames`` counts its filter's extrapolation as no
  surer than the hold (each axis's variance at least the hold's): the bone constraints shrink the posterior of a
  joint nothing measures (mocapbank's right wrist, MediaPipe, lost 74 frames: 7-17 cm claimed in x, y while 25-37
  cm off), and the fusion followed the drift (AKC+(EKF)'s mean 3D RMSE of the lost joints fell on all nine evaluation
  sets, 13.92 -> 11.10 cm on the rig with MediaPipe).
* A shoulder whose depth the occlusion filter dropped, or that the detector lost altogether: its depth (then its
  x, y too) is the filter's fused with the shoulder held on the torso, our outputs' offset from the hips' centre
  while it was seen (a running mean, weight ``shoulder_alpha``, both hips' depths measured) carried by this
  frame's hips, a random walk of ``sigma_shoulder_m^2`` per blind frame (:func:`~akc_drake.core.akc_plus_evidence.
  fuse_held`; an EKF's variance, blind past ``recent_frames``, no less than the hold's): a constant-velocity filter
  that holds the landmark claims a variance that grows without bound, and the arm rebuilt from the elbow then carried
  the elbow's depth error into a shoulder the filter held well (the bench's Motion I, bvhtools_a1's left shoulder
  behind the right hand); one that extrapolates a lost shoulder ran 30 cm off in x. The hips count only when both
  their measured depths pass the innovation test and they are no farther apart than the shoulders; where they have
  been no reference for a second (out of the image), the other shoulder carries it (``akc_plus_torso``).
* A measured shoulder depth that both the shoulder held on the torso (beyond the gate of the hold's and the
  measurement's variances) and the seen elbow contradict (the upper arm from it misses its length by more than
  ``consistency_m``, from the held depth at the same pixel by that much less), or one in front of the held depth
  nearer the measured wrist than the arm can fold (the hand read at the shoulder's pixel), is an occluder's: the
  held depth replaces it on the pixel's ray (:meth:`~akc_drake.core.akc_plus_torso.TorsoReference._torso_outvotes`). A
  filter with no prior left (a shoulder lost for many frames) passes the innovation test by following such a
  reading: mocapbank's, 26 cm in front, moved the seen elbow 7-10 cm.
* A shoulder depth that jumps towards the camera alone (in front of the other shoulder's plus their running-mean
  depth difference, and of its own last depth, beyond the gate) is an occluder's too, held at that difference
  (:meth:`~akc_drake.core.akc_plus_torso.TorsoReference._shoulder_jumped`: MediaPipe's hips, read on a bent body's
  belly, moved with the shoulder read on the head); so is one that jumps behind beyond the shoulder width (the wall).
* A seen elbow that no wrist confirms (the wrist lost, or no anchor) and a shoulder the detector lost altogether, or
  seen farther from it in the image than l_u while the wrist is lost altogether (one x, y is off; which, unknown): the
  arm nearest both in their metric with the exact lengths, not the shoulder kept (mocapbank driven bone by bone: a
  torso that leaned moved the seen elbow 7 cm onto the held shoulder, MediaPipe's seen one 8 cm off 5 cm radially).
* A lost elbow that cannot close the arm at its image x, y from a kept shoulder: the elbow and the wrist share the
  correction in the filter's metric (in depth mostly), not the wrist alone; a detected wrist out of reach: arm straight.
* A seen elbow that the arm nearest the filter's (the lengths' projections) puts more than ``consistency_m`` in
  front of the depth its pixel read: a camera reads the first surface on the ray, so the joint is at or behind it.
  The filter followed an elbow read on a surface in front (MediaPipe on the skinned body, bvhtools_a2: 12-19 cm),
  and the projection tipped to the mirror configuration, the elbow in front of the wrist. The projection from the
  elbow's Pythagorean candidate behind the shoulder replaces it when that leaves the elbow behind its reading, its
  depth nearer our last output's (:func:`~akc_drake.core.akc_plus_lengths.behind_surface`; AKC+(KF)'s worst increase on
  the MediaPipe windows +1.15 -> +0.80 cm). The verdict holds while the pixel reads the same surface and another
  part of the body can cover it, also once the filter and the arm fit the reading, and a filter that followed it
  is no evidence for the elbow lost next (``SurfaceMemory``: the same elbow behind the chest, its wrist then lost;
  AKC+(EKF)'s worst increase on those windows +1.25 -> +0.37 cm).
* A wrist behind a lost elbow, its forearm along the ray (2D length < ``r l_f / (r + consistency_m)``, r =
  ``arm_radius_m``), reads the forearm: if the circle to a kept shoulder moves the elbow off its x, y, the elbow
  goes from the shoulder, the wrist behind its reading (:func:`akc_drake.core.arm_geometry.behind_reading`).
* A measured wrist its own hand hides: the forearm (the filter's elbow to the measured wrist) toward the camera,
  the wrist's pixel reads the hand, up to a hand's length in front (the elbow's depth is dropped then, its pixel
  near the wrist's). The measured knuckles (index and pinky; their midpoint ``hand_length_m``, by default a share
  of the forearm, from the wrist) put it on its pixel ray that far behind them; the filter's wrist moves likewise
  (:func:`~akc_drake.core.arm_geometry.behind_hand`, the teleoperation's rule; the simulated detector read the wrist
  10-16 cm in front on bvhtools_a4, MediaPipe 10-14 on cmu_01_01; the elbow put on the circle to it as far off).
* A seen forearm too long, its wrist the nearer end and the seen elbow fitting its shoulder (seen or held), or
  its wrist behind beyond reach and known worse than the elbow (the wall, followed): the wrist takes the
  correction (``wrist_misfit``). A camera reads a joint in front of where it is (the hand over the wrist) far
  more often than behind (a silhouette's edge, which the gates catch unless the filter followed it); shared, the
  seen elbow took 3-6 cm of the wrist's error (MediaPipe, bvhtools_a1: the wrist read 6-12 cm in front).
* A seen shoulder whose depth agrees with the shoulder held on the torso (within ``consistency_m``) is kept
  against a seen elbow that fits the wrist better than the shoulder fits the elbow (two against two): MediaPipe's
  2D elbow 5 cm off the joint made eq. 8 move such a shoulder 12-18 cm (vicon_playground, cmu_01_01). So is one
  whose rebuild would lie behind its reading while nothing of its own arm covers its pixel (``arm_cover_deg``).
* A shoulder whose upper arm points towards the camera (the elbow in front, its distance in x, y ``d_xy``) reads
  the arm's surface ``r / sin(theta)`` in front of the joint, where the depth offset expects ``r``: with the
  excess ``r (l_u / d_xy - 1)`` above ``consistency_m`` (``arm_radius_m`` = r) it does not count as seen, the
  elbow detected (bvhtools_a3, both detectors: the shoulder read 6-9 cm in front; kept, it moved the elbow 4-5 cm),
  unless read behind the elbow's reading beyond ``l_u`` (no surface of that arm) and no measured wrist fits it.
* A rebuilt shoulder's candidates are weighed against the torso: the held shoulder's depth (the hips' carrying
  our outputs' running-mean offset, with its random walk's variance) when known, else the hips' depth with
  ``sigma_torso_m`` (20 cm). A shoulder read on its own upper arm 24 cm in front is equidistant from both of
  eq. 8's candidates: the hips' depth alone chose the one 50 cm in front of the truth (bvhtools_a1, MediaPipe).
* A joint the detector lost altogether whose depth the filter extrapolates (variance above ``R``, moved by more
  than ``depth_sigma_m`` since last seen) is held at our last output in depth (a zero-velocity hold); a
  filter that holds it, or whose constraints inform it (an EKF), is followed.

Otherwise the arm is **rebuilt**: the Pythagorean candidates (eq. 7-8 with the full calibrated length; x, y
kept when detected; without a solution the nearest point at the length, at the anchor's depth when x, y were
detected, radially when not) are scored as Gaussian log-likelihoods::

    J = |p - p̂|^2 / sigma_f^2 + min(|p - p_prev|^2 / sigma_t^2, cap^2) [+ width, torso and anatomy terms]

with ``sigma_f^2`` the filter's covariance-matched depth variance (no prior when the filter's estimate was
replaced or follows a rejected depth). A seen shoulder is kept and the elbow goes on the circle between it
and the wrist (the wrist follows when that would move a seen elbow, or a lost elbow of a wrist not measured in
3D, by more than ``xy_tol_m`` off its image x, y: a wrist measured in 3D keeps its place, the detector's 2D
elbow is off the joint centre too; with MediaPipe 3-7 cm, and moving the wrist turned that into 10-20 cm of
depth error; a 2D elbow farther from that wrist's than l_f, where eq. 7-8 have no depth, takes the circle's
points nearest its x, y: ``arm_geometry.circle_xy_pair``). When neither is kept and all three joints' x, y were
detected, the candidates choose the configuration (the side of the image plane each segment points to): a
filter's arm that bends the same way and passes the lengths' chi2 test gives the estimate instead, the arm
nearest it with the exact lengths (as for known depths: eq. 7-8 take the detected x, y as exact, the projection
weighs them, the filter's depths and the lengths by their variances). The temporal term is capped so that
persistent evidence can undo a wrong configuration; a mirror switch needs evidence over several frames. The
anatomical tests (elbow folded below ``elbow_min_deg``, hyperextended by m5's signed angle) are a finite penalty
of 5 standard deviations squared, no veto (both are tests on noisy positions near their limits).

**Without the covariance** (``variance=None``; the system's variance input unconnected): the rules of the previous
revision: seen = within ``consistency_m`` of the filter and ``jump_m`` of our last output (unless persisting
``gate_frames`` frames and fitting the arm); ``sigma_f`` grows with the blind frames and the filter's travel
since last seen; seen joints move only as the exact lengths require (circle / wrist follows).

No shrink factor (seen depths make the near-in-plane instability moot). Every output arm has exactly the
calibrated lengths (to rounding). Plain Python floats on the hot path (numpy calls cost more than the arithmetic).
Evidence: :mod:`akc_drake.core.akc_plus_evidence`; candidates' costs and choices: :mod:`akc_drake.core.akc_plus_search`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from akc_drake.core.akc import AKCResult
from akc_drake.core.akc_plus_config import AKCPlusConfig, hand_lengths, per_frame
from akc_drake.core.akc_plus_evidence import (
    arm_variances,
    beyond_reach,
    followed_rejected,
    fuse_held,
    held_segments,
    hidden_wrist,
    hold_blind,
    known_depths,
    unreachable_replacements,
    wrist_misfit,
)
from akc_drake.core.akc_plus_lengths import (
    SurfaceMemory,
    anchored_wrist,
    behind_surface,
    circle_pair,
    learn_elbow_offset,
    measured_arm,
    project_arm,
    project_forearm,
    same_configuration,
    sphere_point,
)
from akc_drake.core.akc_plus_search import CandidateSearch
from akc_drake.core.akc_plus_state import STATE_SIZE, StateVector  # noqa: F401 (STATE_SIZE: public here too)
from akc_drake.core.akc_plus_torso import _XYZ, NO_HIPS, TorsoReference, learn_offset
from akc_drake.core.arm_geometry import arm_inputs, circle_xy_pair, covered_excess, drop_unreadable, ray_check
from akc_drake.core.arm_geometry import behind_reading as _behind_reading
from akc_drake.core.arm_geometry import candidates as _candidates
from akc_drake.core.arm_geometry import circle_point as _circle_point
from akc_drake.core.arm_geometry import d2 as _d2
from akc_drake.core.arm_geometry import follow as _follow
from akc_drake.core.arm_geometry import nearest_depth as _nearest_depth
from akc_drake.core.arm_geometry import pythagoras as _pythagoras
from akc_drake.core.arm_geometry import radial as _radial
from akc_drake.core.arm_geometry import straight_arm as _straight
from akc_drake.core.arm_geometry import turn_with as _turn_with
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, SIDES, BodyDimensions, side_indices

if TYPE_CHECKING:  # (read by Cython when compiling: typed indices, see setup.py; never imported at run time)
    import cython

_hypot, _inf, _isfinite = math.hypot, math.inf, math.isfinite
_NAN, _F64 = float("nan"), np.dtype(np.float64)


def _as_f64(x):
    """``x`` as a float64 array (``np.asarray`` with a dtype costs about 1 µs even when it has nothing to do)."""
    return x if type(x) is np.ndarray and x.dtype == _F64 else np.asarray(x, dtype=np.float64)


_FLAT, _SHAPE = 3 * NUM_LANDMARKS, (NUM_LANDMARKS, 3)
_HAND = tuple(tuple(3 * INDEX[f"{s}_{j}"] for j in ("elbow", "wrist", "index", "pinky")) for s in SIDES)


class ArmKinematicCorrectorPlus(CandidateSearch, TorsoReference, SurfaceMemory, StateVector):
    """AKC+ for both arms (see the module docstring); the same interface as the paper's corrector.

    Args:
        dims: the calibrated body dimensions.
        config: settings.
        period_s: the frame period, seconds (None: 10 Hz, the rate the per-frame settings are stated at); the
            rate-dependent settings are scaled to it (:func:`~akc_drake.core.akc_plus_config.per_frame`).

    Missing inputs are handled as the paper's corrector does: a missing wrist holds the arm's last
    output (NaN if none); a missing elbow/shoulder x, y reuses the last output's (held if none).
    """

    # Slots: this object's attributes are read tens of times a frame on the hot path.
    __slots__ = ("config", "_arm_index", "_axes", "_chi2_gate", "_cos_min", "_cur_var", "_dims", "_f0", "_fits",
                 "_gate2", "_inv_t2", "_inv_torso2", "_inv_w2", "_inv_wrist2", "_len_var", "_lf", "_lost", "_off_var",
                 "_v_t", "_hand", "_ls", "_lu", "_nis", "_no_measurement", "_no_prior", "_occ_r2", "_offsets", "_prev",
                 "_r_axes", "_r_z", "_sub_index", "_nis_a", "_nis_floor", "_tol", "_cons", "_xy_tol", "_t_cap",
                 "_travel", "_v", "_v0", "_var", "_blind", "_blind_e", "_held_sh", "_v_s", "_a_s", "_hips", "_tz",
                 "_inv_tz2", "_fs_r", "_fs_k2", "_fa_r", "_refit", "_pf", "_held_ss", "_anchor", "_hips_lost",
                 "_s_floor", "_pair_z", "_blind_honest", "_cover2", "_width_gate", "_wrist_anchor", "_seen_var",
                 "_read_e", "_verdict", "_depth_noise", "_fuse", "_e_acc",
                 "_e_var", "_e_alpha", "_e_cap")

    def __init__(self, dims: BodyDimensions, config: AKCPlusConfig | None = None, period_s: float | None = None):
        if not isinstance(dims, BodyDimensions):
            raise ValueError(f"dims must be a BodyDimensions, got {type(dims).__name__}")
        config = AKCPlusConfig() if config is None else config
        if not isinstance(config, AKCPlusConfig):
            raise ValueError(f"config must be an AKCPlusConfig, got {type(config).__name__}")
        self._dims = dims
        self.config = config
        self._lf, self._lu, self._ls = (dims.LLA, dims.RLA), (dims.LUA, dims.RUA), dims.SW
        self._offsets = tuple(tuple(3 * i for i in side_indices(side)) for side in SIDES)
        self._hand = tuple((*o, k) for o, k in zip(_HAND, hand_lengths(config, self._lf), strict=True) if k > 0)
        self._pf = pf = per_frame(config, period_s)  # (the rate-dependent settings at this frame period)
        self._inv_t2, self._t_cap = 1.0 / pf.step_sigma_m**2, config.temporal_cap**2
        self._v_t, self._v_s, self._a_s = pf.temporal_walk_var, pf.shoulder_walk_var, pf.shoulder_alpha
        self._inv_w2 = 1.0 / config.sigma_width_m**2 if config.sigma_width_m > 0 else 0.0
        self._inv_wrist2, self._fuse = 1.0 / config.sigma_filter_m**2, config.seen_depth_fusion is not False
        self._inv_torso2 = 1.0 / config.sigma_torso_m**2 if config.sigma_torso_m > 0 else 0.0
        self._no_prior, self._fits, self._cos_min = set(), set(), math.cos(math.radians(config.elbow_min_deg))
        self._r_z, self._len_var = config.depth_sigma_m**2, config.length_sigma_m**2
        self._off_var = 0.5 * self._len_var  # (the projections' landmark-offset variance per coordinate: ``_arm``)
        self._e_alpha, self._e_cap = config.elbow_offset_alpha, 5.0 * config.length_sigma_m  # (``learn_elbow_offset``)
        self._r_axes = (config.image_sigma_m**2, config.image_sigma_m**2, config.depth_sigma_m**2)
        # Flat indices of each arm's nine coordinates, and (position in the arm, flat index, R) per coordinate.
        self._arm_index = tuple(tuple(o + ax for o in offs for ax in range(3)) for offs in self._offsets)
        self._sub_index = tuple(tuple((i, j, self._r_axes[i % 3], 9 * side + i) for i, j in enumerate(idx))
                                for side, idx in enumerate(self._arm_index))
        self._no_measurement, self._gate2 = [_NAN] * (3 * NUM_LANDMARKS), config.gate_sigma**2
        # (two measured points farther apart than a width reaches: the gate of both their variances and the width's)
        self._width_gate = self._gate2 * (2.0 * (self._r_axes[0] + self._r_axes[1] + self._r_axes[2]) + self._len_var)
        # Settings read on the hot path, as plain attributes (one lookup instead of two).
        self._nis_a, self._nis_floor, self._tol = pf.nis_alpha, config.nis_floor, config.length_tol_m
        self._refit, self._wrist_anchor = config.constrained_filter is True, config.seen_wrist_anchor is True
        # A constrained filter's variance of a joint lost altogether is no error measure after ``recent_frames``.
        self._blind_honest, self._fa_r = pf.recent_frames if self._refit else _inf, config.forearm_radius_m
        self._seen_var = config.seen_depth_sigma_m**2 if self._refit or self._fuse else 0.0
        self._cons, self._xy_tol, self._occ_r2 = config.consistency_m, config.xy_tol_m, config.occlusion_radius_m**2
        # The foreshortened upper arm's rule (``arm_radius_m``): d_xy (r + consistency_m) < r l_u, squared.
        self._fs_r, self._fs_k2 = config.arm_radius_m, (config.arm_radius_m + config.consistency_m) ** 2
        self._cover2 = math.sin(math.radians(config.arm_cover_deg)) ** 2  # (``_outvoted``: d_xy^2 < l_u^2 cover2)
        # chi2 with 2 degrees of freedom at the tail probability of gate_sigma (1 dof): -2 ln(erfc(g / sqrt 2)).
        self._chi2_gate = -2.0 * math.log(max(math.erfc(config.gate_sigma / math.sqrt(2.0)), 1e-300))
        self._var = self._v = self._v0 = self._axes = self._cur_var = None
        self._tz, self._inv_tz2, self._hips, self._anchor, self._s_floor = _NAN, 0.0, NO_HIPS, [None, None], _NAN
        self.reset()

    @property
    def dims(self) -> BodyDimensions:
        return self._dims

    # ------------------------------------------------------------------ hot path (plain floats)
    def _measured(self, m, o, fz):
        """Without the filter's covariance: whether row ``m[o:o+3]`` was measured this frame and its depth is
        within ``consistency_m`` of the filtered ``fz`` (with it, ``_arm`` runs the innovation test inline)."""
        if m is None or not _isfinite(m[o] + m[o + 1] + m[o + 2]):
            return False
        return abs(m[o + 2] - fz) <= self.config.consistency_m

    def _arm(self, v, m, side: cython.Py_ssize_t):
        """The corrected arm (9 floats: shoulder, elbow, wrist) or None to hold; also updates the counters."""
        sx: float; sy: float; sz: float; ex: float; ey: float; ez: float; wx: float; wy: float; wz: float; z: float
        q: float; d: float; d0: float; d1: float; d2: float; df: float; jump: float; inv_w2: float; lf: float; lu: float
        g2: float; rz: float; tol: float; cons: float  # (C doubles when compiled: setup.py)
        o_s: cython.Py_ssize_t; o_e: cython.Py_ssize_t; o_w: cython.Py_ssize_t
        prev, self._verdict = self._prev[side], False
        o_s, o_e, o_w = offsets = self._offsets[side]
        inputs = arm_inputs(v, offsets, prev)  # (wrist lost: hold; x, y or depth missing: prev's or a neighbour's)
        if inputs is None:
            return None
        sx, sy, sz, ex, ey, ez, wx, wy, wz = inputs
        var = self._var
        s_held = e_fused = False  # the shoulder held on the torso, the elbow fused with its held upper arm
        if var is not None:
            f = [sx, sy, sz, ex, ey, ez, wx, wy, wz]
            vs = self._cur_var = arm_variances(self._sub_index[side], var, self._no_measurement if m is None else m,
                                               self._v, f, self._nis, self._nis_a, self._nis_floor, self._gate2,
                                               self._refit, self._seen_var, self._depth_noise if self._fuse else None)
            if m is not None and m[o_s + 2] != m[o_s + 2]:  # (a shoulder's depth not read: the seen elbow carries it)
                vs[5] += covered_excess(*m[o_e:o_e + 3], *m[o_w:o_w + 3], self._lf[side], self._fa_r) ** 2
            if m is not None and (m[o_s] != m[o_s] or m[o_w] != m[o_w]):  # (a joint lost altogether that its
                # filter put beyond the measured elbow's reach)
                beyond_reach(f, vs, m, offsets, prev, self._lu[side], self._lf[side], self._r_axes, self._len_var,
                             self._gate2)
            if m is not None and m[o_s + 2] != m[o_s + 2]:
                # A shoulder whose depth was dropped, or lost altogether (no x, y either): the filter's estimate
                # and the shoulder held on the torso, fused (``vs[2]`` NaN: a depth the filter does not know, left
                # as it is; ``_anchor`` None: the hold off, or neither the hips nor the other shoulder seen).
                a = self._anchor[side]
                if a is not None and vs[2] == vs[2]:
                    s_held = self._hold_on_torso(f, vs, m, side, a)
            elif m is not None and vs[2] == vs[2]:
                s_held = self._torso_outvotes(f, vs, m, side)
            if m is not None:  # (a depth that jumped towards the camera, alone)
                s_held = self._shoulder_jumped(f, vs, m, side, s_held)
                # A depth the innovation test rejects: the ray test decides (inlined pre-test; NaN is False); before
                # the held segments carry a lost joint (a diverged EKF's shoulder flipped a lost wrist 40 cm a frame).
                g2, rz = self._gate2, self._r_z
                d0, d1, d2 = m[o_s + 2] - f[2], m[o_e + 2] - f[5], m[o_w + 2] - f[8]
                if (d0 * d0 > g2 * (rz - var[o_s + 2]) or d1 * d1 > g2 * (rz - var[o_e + 2])
                        or d2 * d2 > g2 * (rz - var[o_w + 2])):
                    ray_check(m, offsets, f, vs, var, self._r_axes[0], rz, g2, self._chi2_gate,
                              prev, self._cons)
            # An elbow, then a wrist, lost altogether (no x, y): the filter's extrapolation and the segment held
            # at the joint before it (the shoulder, then the elbow, as fused), fused.
            if m is not None and self._blind_e[side] is not None and m[o_e] != m[o_e] and m[o_e + 1] != m[o_e + 1]:
                fuse_held(f, vs, self._blind_e[side], f[0:3], self._v_t, 3, _XYZ, self._blind_honest,
                          self._read_e[side] == self._read_e[side])  # (a filter that followed an occluder: none)
                e_fused = True
            b = self._blind[side]
            if m is not None and b is not None and m[o_w] != m[o_w] and m[o_w + 1] != m[o_w + 1]:
                if b[4] == b[4]:
                    if not _isfinite(m[o_e] + m[o_e + 1]):
                        b[4] = b[5] = b[6] = _NAN  # (the upper arm not followed: the forearm no longer turns)
                    else:
                        # The held forearm turns with the upper arm since the wrist was last seen (one arm swinging
                        # about the shoulder; held fixed in the camera frame, it lagged: mocapbank, simulated, +0.54
                        # cm over the KF in y -> +0.33), only while the elbow has been seen throughout (an upper arm
                        # rebuilt without it turned the forearm with its own error: MediaPipe boxing, +3.3 cm).
                        b = [*_turn_with(b[0], b[1], b[2], b[4], b[5], b[6], f[3] - f[0], f[4] - f[1], f[5] - f[2]),
                             b[3]]
                fuse_held(f, vs, b, f[3:6], self._v_t, 6, _XYZ, self._blind_honest, self._blind[side][7] > 0.0)
                self._blind[side][3] = b[3]
            if m is not None and (f[2] != sz or f[5] != ez or f[8] != wz):
                # A measured point that replaced the filter's must be within the arm's reach of its neighbours.
                unreachable_replacements(f, vs, (sx, sy, sz, ex, ey, ez, wx, wy, wz), m, offsets, self._sub_index[side],
                                         var, self._nis, self._nis_floor, self._lu[side], self._lf[side], self._r_axes,
                                         self._len_var, self._gate2, s_held or self._torso_confirms(f, m, side))
            sx, sy, sz, ex, ey, ez, wx, wy, wz = f
        else:
            vs = self._cur_var = None
        lf, lu, ev = self._lf[side], self._lu[side], self._e_var[side]  # (ev: ``learn_elbow_offset``, ``correct``)
        ke, ks = 2 * side, 2 * side + 1
        no_prior = self._no_prior = set()
        tol = self._tol
        # Measured this frame and consistent with the filter (the filter is then a good prior) ...
        # ``*_nis``: the filter followed the depth: it passes the test and the filter moved towards it since last seen
        # (not one its constraints moved away, or kept), or it fails and the filter followed it (``followed_rejected``).
        if m is None or var is None:
            me, ms = self._measured(m, o_e, ez), self._measured(m, o_s, sz)
            me_nis = ms_nis = False
        else:  # (``_measured``'s innovation test, inlined: this runs every frame)
            g2, rz, f0 = self._gate2, self._r_z, self._f0
            z, q = m[o_e + 2], rz - var[o_e + 2]
            d = (z - ez) ** 2
            me = _isfinite(m[o_e] + m[o_e + 1] + d) and d <= g2 * (q if q > 0.0 else 0.0) + 1e-12
            me_nis = (f0[ke] is None or d < (z - f0[ke][2]) ** 2) if me else followed_rejected(z, ez, prev, 5, g2 * rz)
            z, q = m[o_s + 2], rz - var[o_s + 2]
            d = (z - sz) ** 2
            ms = _isfinite(m[o_s] + m[o_s + 1] + d) and d <= g2 * (q if q > 0.0 else 0.0) + 1e-12
            ms_nis = (f0[ks] is None or d < (z - f0[ks][2]) ** 2) if ms else followed_rejected(z, sz, prev, 2, g2 * rz)
        if prev is not None and var is None:
            geo_f = abs(_hypot(ex - wx, ey - wy, ez - wz) - lf) <= tol
            geo_u = abs(_hypot(sx - ex, sy - ey, sz - ez) - lu) <= tol
            # (With the filter's covariance the innovation test of ``_measured`` is this test.)
            # Consistent with the prediction (our last output): a seen depth that jumps by more than jump_m in
            # one frame is an occluder's until it fits the arm again or has stayed for gate_frames frames.
            jump, n = self._pf.jump_m, self._pf.gate_frames
            if me and abs(m[o_e + 2] - prev[5]) > jump and not (self._lost[ke] >= n and geo_f):
                me = False
            if ms and abs(m[o_s + 2] - prev[2]) > jump and not (self._lost[ks] >= n and geo_u):
                ms = False
        # x, y detected this frame (else the filter holds them: no reliable 2D for eq. 7-8)
        exy = m is None or _isfinite(m[o_e] + m[o_e + 1])
        sxy = m is None or _isfinite(m[o_s] + m[o_s + 1])
        if prev is not None and m is not None:
            # A joint the detector lost altogether: a filter without a hold extrapolates it at its last velocity,
            # and our last output (no evidence: the filter prior is then left out) is the better estimate: without
            # the covariance when the filter moved it more than jump_m from it; with it, see ``hold_blind``.
            if vs is None:
                jump = self._pf.jump_m
                if not exy and _hypot(ex - prev[3], ey - prev[4], ez - prev[5]) > jump:
                    ex, ey, ez = prev[3], prev[4], prev[5]
                    self._no_prior.add(2 * side)
                if not sxy and _hypot(sx - prev[0], sy - prev[1], sz - prev[2]) > jump:
                    sx, sy, sz = prev[0], prev[1], prev[2]
                    self._no_prior.add(2 * side + 1)
            else:
                if not exy and not e_fused:  # (a fused elbow: its hold is the upper arm's)
                    (ex, ey, ez), held = hold_blind((ex, ey, ez), vs, 3, self._f0[ke], prev, self._r_z)
                    if held:
                        no_prior.add(ke)
                if not sxy:
                    (sx, sy, sz), held = hold_blind((sx, sy, sz), vs, 0, self._f0[ks], prev, self._r_z)
                    if held:
                        no_prior.add(ks)
        # Our proximity rule for the pair the paper's occlusion filter lacks (a shoulder within occlusion_radius_m of
        # its detected elbow in the image, or whose upper arm points at the camera: the module docstring), unless read
        # behind the elbow's reading beyond l_u's reach (no arm's surface) and no measured wrist fits the elbow.
        if ms and exy:
            d2 = (sx - ex) ** 2 + (sy - ey) ** 2
            if d2 < self._occ_r2 or (ez < sz and d2 * self._fs_k2 < (self._fs_r * lu) ** 2):
                ms = m[o_s + 2] - m[o_e + 2] > lu + self._cons and not (
                    me and m[o_w + 2] == m[o_w + 2] and abs(_hypot(ex - wx, ey - wy, ez - wz) - lf) <= tol)
        if vs is not None:
            # A depth rejected (by the test, or another rule: proximity) that the filter followed (``*_nis``): the
            # filter's estimate and (small) variance are no independent evidence; its prior is left out.
            if not me and me_nis:
                no_prior.add(ke)
            if not ms and ms_nis:
                no_prior.add(ks)
        # A lost depth at its length (to the wrist, the filtered elbow) within consistency_m: no drift, its full prior.
        if vs is None:  # (only the no-covariance prior uses it)
            cons = self._cons
            self._fits = set()
            if not me and ke not in self._no_prior and abs(_hypot(ex - wx, ey - wy, ez - wz) - lf) <= cons:
                self._fits.add(ke)
            if not ms and ks not in self._no_prior and abs(_hypot(sx - ex, sy - ey, sz - ez) - lu) <= cons:
                self._fits.add(ks)
        # How far the filter's depth has travelled since last seen (a filter that jumps or drifts to another
        # depth while blind is no evidence for it; one that stays where it was is).
        f0, travel, lost = self._f0, self._travel, self._lost
        if me or f0[ke] is None:
            f0[ke], travel[ke] = (ex, ey, ez), 0.0
        else:
            travel[ke] = abs(ez - f0[ke][2])
        if ms or f0[ks] is None:
            f0[ks], travel[ks] = (sx, sy, sz), 0.0
        else:
            travel[ks] = abs(sz - f0[ks][2])
        lost[ke], lost[ks] = (0.0 if me else lost[ke] + 1.0), (0.0 if ms else lost[ks] + 1.0)
        # With the covariance: a depth not measured this frame that the filter knows as well as a measurement or
        # better than eq. 7-8 would rebuild it counts as known (a rejected or held one does not; ``known_depths``).
        kn_e, kn_s = me, ms
        if vs is not None and not (me and ms):
            kn_e, kn_s = known_depths(m, vs, me, ms, o_e, o_s, ke, ks, lu, lf, (sx, sy, ex, ey, wx, wy), self._r_z,
                                      self._len_var, no_prior, self._lost, self._pf.recent_frames)
        projected = vs is not None and kn_e and kn_s  # (the projection of the filter's arm, tried)
        if projected:
            # Both depths known: the arm nearest the filter's in its metric with the exact lengths, if it passes the
            # lengths' chi2 test (the module docstring's "Minimal change": the metric adds each landmark's offset,
            # ``_off_var``, the elbow's learnt, ``_e_var``); after an EKF the test judges the arm as measured.
            t = measured_arm(m, offsets) if self._refit else None
            a9 = (sx, sy, sz, ex, ey, ez, wx, wy, wz)
            arm = project_arm(a9, vs, lu, lf, 0.0, self._chi2_gate, self._off_var, t, ev)
            if arm is not None:  # (an elbow not in front of the surface its pixel read: ``behind_surface``)
                if me and prev is not None and (t := self._surface_tol(side, m[o_e + 2], arm[5], o_e)) == t:
                    return self._judged(arm, behind_surface(arm, a9, vs, lu, lf, m[o_e + 2], t, prev[5], self._off_var))
                return arm
        pe = (prev[3], prev[4], prev[5]) if prev is not None else None
        w = (wx, wy, wz)
        s = e = None
        df = abs(_hypot(ex - wx, ey - wy, ez - wz) - lf) if me else _inf
        te = df <= tol  # elbow seen and at l_f from the wrist
        # A seen shoulder is trusted unless a seen elbow that fits the wrist outvotes it (``_outvoted``: then its
        # rebuild, reused below). One lost altogether (no x, y) is kept where held (eq. 8 needs its 2D position; a
        # wrong elbow is likelier).
        outvoted = ms and te and self._outvoted(side, (sx, sy, sz, ex, ey, ez), w, prev, ks, lu, lf, sxy, df,
                                                m[o_s + 2])
        ts = (ms and not outvoted) or (not sxy and prev is not None and not te) or (kn_s and not te)
        # A wrist lost altogether (no x, y), known worse than the elbow and shoulder or than the shoulder and beyond
        # the arm's reach from it, is no anchor (eq. 7-8 would carry its extrapolation into the seen joints): the arm
        # is built from the shoulder out; so is a wrist whose measured depth was rejected (the filter or the reading).
        w_lost, w_read = False, _NAN
        if vs is not None and m is not None:
            # (``w_bad``: the innovation test of the wrist's depth, NaN passing; run only here, where it can act.)
            z, q = m[o_w + 2], self._r_z - self._var[o_w + 2]
            w_lost = z == z and (z - wz) ** 2 > self._gate2 * (q if q > 0.0 else 0.0) + 1e-12
            if not w_lost and not _isfinite(m[o_w] + m[o_w + 1]):
                w_lost = vs[8] > vs[2] and (vs[8] > vs[5] or _hypot(wx - sx, wy - sy, wz - sz) > lu + lf + tol)
            if not w_lost and me and z == z and _isfinite(m[o_w] + m[o_w + 1]):
                # A wrist too far from a seen elbow: its nearer end (two against one), or behind beyond reach.
                w_lost = wrist_misfit((sx, sy, sz, ex, ey, ez, wx, wy, wz), vs, lu, lf, self._cons, ms or s_held)
        if w_lost:
            if me and not ts and not s_held and _hypot(m[o_e] - ex, m[o_e + 1] - ey, m[o_e + 2] - ez) <= self._cons:
                # (A shoulder kept only for want of the wrist yields to a seen elbow: the module's docstring.)
                sx, sy, sz = _nearest_depth(ex, ey, ez, sx, sy, sz, lu)
            ts, te = True, False
        if vs is not None and me and not te and prev is not None and (not sxy or (
                ms and m is not None and not _isfinite(m[o_w] + m[o_w + 1]) and _hypot(sx - ex, sy - ey) > lu)):
            # A seen elbow that no wrist confirms, and a shoulder the detector lost altogether or seen farther from it
            # in the image than l_u while the wrist is lost altogether: the arm nearest both in their metric with the
            # exact lengths, not the shoulder kept (the module docstring).
            arm = project_arm((sx, sy, sz, ex, ey, ez, wx, wy, wz), vs, lu, lf, 0.0, _inf, self._off_var, None, ev)
            if arm is not None:
                return arm
        if ts:
            # A seen shoulder is kept. The elbow goes on the circle at l_f from the wrist and l_u from the
            # shoulder, nearest its filtered position (seen elbow) or its Pythagorean candidate (eq. 7) ...
            s = (sx, sy, sz)
            w_seen = False
            if te:
                e = _circle_point(wx, wy, wz, sx, sy, sz, lf, lu, ex, ey, ez)
                if e is not None and _d2(e, ex, ey, ez) > self._xy_tol ** 2:
                    e = None  # the wrist (a lagging filter's) would move the seen elbow: the wrist moves instead
            elif not me and not w_lost:
                # A wrist measured in 3D (its depth passed the innovation test) and a kept shoulder: the elbow whose
                # depth was lost goes on the circle between them even off its image x, y (MediaPipe's 2D elbow is 3-7
                # cm off the joint: the wrist moved instead carried it into the depths, 10-20 cm).
                w_seen = vs is not None and m is not None and _isfinite(m[o_w] + m[o_w + 1] + m[o_w + 2])
                pair = _pythagoras(wx, wy, wz, ex, ey, lf) if exy else None
                if pair is not None or (exy and w_seen):
                    # (The circle exists for both or neither: it depends on s, w alone. No pair: ``circle_xy_pair``.)
                    qq = (circle_pair(wx, wy, wz, sx, sy, sz, lf, lu, pair[0], pair[1]) if pair is not None else
                          circle_xy_pair(wx, wy, wz, sx, sy, sz, lf, lu, ex, ey))
                    if qq is not None:
                        q1, q2 = qq
                        # (Both off the elbow's image position: whichever is chosen is discarded below.)
                        if w_seen or not (_hypot(q1[0] - ex, q1[1] - ey) > self._xy_tol
                                          and _hypot(q2[0] - ex, q2[1] - ey) > self._xy_tol):
                            e = self._choose_elbow(qq, ex, ey, ez, pe, ke, s, w, lu, lf)
                        if (w_seen and e is not None and e[2] < wz + self._cons and _hypot(e[0] - ex, e[1] - ey)
                                > self._xy_tol and ((ex - wx) ** 2 + (ey - wy) ** 2) * self._fs_k2
                                < (self._fs_r * lf) ** 2):  # (... but not a wrist that reads its forearm: see above)
                            w_lost, w_seen, w_read, e = True, False, m[o_w + 2], None
            if e is None or (not w_seen and _hypot(e[0] - ex, e[1] - ey) > self._xy_tol):
                # ... unless that moves the elbow off its image position (the filtered wrist lags, is off, or
                # contradicts a seen elbow): then the elbow is placed from the shoulder (radially when seen, else the
                # shoulder's Pythagorean candidate, x, y kept, that best fits the filter, the previous output and the
                # wrist) and the wrist at l_f from it along its own direction.
                if me:  # (behind the surface its pixel read, as judged last frame: ``SurfaceMemory``)
                    e = _radial(sx, sy, sz, ex, ey, ez, lu)
                    if pe is not None:
                        e = self._behind_radial(side, o_e, s, e, ex, ey, m[o_e + 2], pe[2], lu)
                else:
                    # The Pythagorean pair (x, y kept) and the point at l_u nearest the filter's estimate
                    # (the filter's own elbow when only the lengths contradict it).
                    cands = _candidates(sx, sy, sz, ex, ey, ez, lu, exy, tol) + (_radial(sx, sy, sz, ex, ey, ez, lu),)
                    inv_w2 = 1.0 / max(vs[8], 1.0 / self._inv_wrist2) if w_lost else self._inv_wrist2
                    e = self._choose_elbow(cands, ex, ey, ez, pe, ke, s, w, lu, lf, inv_w2)
                if vs is not None and not w_lost:
                    # With the covariance, the wrist does not take the whole correction: the elbow (its image x, y,
                    # this depth) and the wrist move as little as their variances allow (the kept shoulder fixed),
                    # mostly in depth; not a measured wrist beyond the gate in x, y with ``seen_wrist_anchor``.
                    arm = project_forearm(s, (ex, ey, e[2], wx, wy, wz), vs[3:], lu, lf, self._off_var)
                    if self._wrist_anchor and (kept := anchored_wrist(arm, s, (ex, ey, ez), w, m, o_w, vs, lu, lf,
                                                                      self._off_var, self._gate2)):
                        return kept
                    if arm is not None:  # (as after the projection above)
                        if me and pe is not None and (t := self._surface_tol(side, m[o_e + 2], arm[5], o_e)) == t:
                            return self._judged(arm, behind_surface(arm, (*s, ex, ey, e[2], wx, wy, wz), vs, lu, lf,
                                                                    m[o_e + 2], t, pe[2], self._off_var, True))
                        return arm
                    if m is not None and _isfinite(m[o_w] + m[o_w + 1]) and (arm := _straight(*s, wx, wy, wz, lu, lf)):
                        return arm  # (a detected wrist beyond the kept shoulder's reach: ``straight_arm``)
                if w_lost and vs is not None:  # A wrist no anchor: at l_f from the elbow, behind a reading of its
                    # forearm, nearest in its own metric (depth rejected) or radially (not detected: README "AKC+").
                    w = (w_read == w_read and _behind_reading(*e, wx, wy, w_read, lf)) or (
                        sphere_point(e[0], e[1], e[2], wx, wy, wz, vs[6], vs[7], vs[8], lf)
                        if _isfinite(m[o_w] + m[o_w + 1]) else _radial(e[0], e[1], e[2], wx, wy, wz, lf))
                else:
                    w = _follow(e[0], e[1], e[2], wx, wy, wz, lf)
            return (*s, *e, *w)
        # Neither joint kept: the elbow from the wrist (a seen elbow radially) and the shoulder from the elbow.
        if outvoted:  # (rebuilt already, by ``_outvoted``)
            s, e = outvoted
        else:
            self._prepare_rebuild(side, _NAN if m is None else m[o_s + 2], wz, lu, lf)
            ps = (prev[0], prev[1], prev[2]) if prev is not None else None
            f6, other = (sx, sy, sz, ex, ey, ez), self._other_shoulder(side)
            s, e = (self._rebuild_shoulder(f6, w, ps, ks, lu, lf, sxy, other) if te
                    else self._rebuild_from_wrist(f6, w, pe, ps, ke, ks, lu, lf, exy, sxy, other))
        if (vs is not None and not projected and exy and sxy and m is not None and ke not in no_prior
                and ks not in no_prior and _isfinite(m[offsets[2]] + m[offsets[2] + 1])):
            # The candidates chose the configuration (which side of the image plane each segment points to); when
            # the filter's arm has the same one and passes the lengths' chi2 test, the arm nearest it with the exact
            # lengths (the projection above) is the estimate: the rebuilt depths take eq. 7-8's x, y as exact, the
            # projection weighs them, the filter's depths and the lengths by their variances (not when tried above).
            arm = project_arm((sx, sy, sz, ex, ey, ez, wx, wy, wz), vs, lu, lf, 0.0, self._chi2_gate, self._off_var,
                              None, ev)
            if arm is not None and same_configuration(arm, s[2], e[2], wz):
                return arm
        return (*s, *e, *w)

    def correct(self, pose, measured=None, variance=None) -> AKCResult:
        """Correct one filtered pose.

        Args:
            pose: ``(12, 3)`` filtered landmarks in the camera frame, NaN where missing.
            measured: ``(12, 3)`` this frame's measurement after the occlusion filter (NaN where rejected
                or where the depth was dropped), or None when there is none (no depth is trusted).
            variance: ``(12, 3)`` the filter's posterior variance of each coordinate of ``pose`` (the KF's and
                EKFs' ``position_variance``), or None (then ``depth_sigma_m`` and ``image_sigma_m`` stand for it).

        Returns:
            An :class:`~akc_drake.core.akc.AKCResult`; ``chosen`` is 0 for a corrected arm (-1 held),
            ``fallback`` marks arms with no trusted depth, ``cost`` is NaN.

        Raises:
            ValueError: if ``pose`` or ``measured`` does not have shape (12, 3).
        """
        o_s: cython.Py_ssize_t; o_e: cython.Py_ssize_t; o_w: cython.Py_ssize_t  # (C indices when compiled: setup.py)
        a = pose if type(pose) is np.ndarray and pose.dtype == _F64 else _as_f64(pose)  # (inline)
        if a.shape != _SHAPE:
            raise ValueError(f"pose must have shape ({NUM_LANDMARKS}, 3), got {a.shape}")
        v = a.reshape(_FLAT).tolist()  # (reshape: about 0.1 us less than ravel)
        m = None
        if measured is not None:
            b = measured if type(measured) is np.ndarray and measured.dtype == _F64 else _as_f64(measured)  # (inline)
            if b.shape != _SHAPE:
                raise ValueError(f"measured must have shape ({NUM_LANDMARKS}, 3), got {b.shape}")
            m = b.reshape(_FLAT).tolist()
            drop_unreadable(m)  # (a depth nearer than MIN_DEPTH_M: no reading; its ray is degenerate)
            for o in self._hand:  # (a wrist its own hand hides, put behind it: ``hidden_wrist``)
                hidden_wrist(v, m, o[0], o[1], o[2], o[3], o[4])
        self._var = None
        if variance is not None:
            c = variance if type(variance) is np.ndarray and variance.dtype == _F64 else _as_f64(variance)  # (inline)
            if c.shape != _SHAPE:
                raise ValueError(f"variance must have shape ({NUM_LANDMARKS}, 3), got {c.shape}")
            self._var = c.reshape(_FLAT).tolist()
        self._v = v
        self._axes = None  # (see ``_penalty``)
        self._v0 = v[:]
        chosen, held, fallback = [-1, -1], [True, True], [False, False]
        prevs, lost, offsets = self._prev, self._lost, self._offsets
        # The torso's references of the held shoulders (``TorsoReference._torso_anchors``): the hips' centre, or the
        # other shoulder.
        hold, hips, others = self._torso_anchors(v, m)
        held_sh, held_ss = self._held_sh, self._held_ss
        for side in (0, 1):
            ke = 2 * side
            lost_e, lost_s = lost[ke], lost[ke + 1]
            o_s, o_e, o_w = offsets[side]
            self._e_var[side] = learn_elbow_offset(self._e_acc[side], m, o_s, o_e, o_w, self._lu[side], self._lf[side],
                                                   self._e_alpha, self._e_cap, self._off_var)
            out = self._arm(v, m, side)  # (the other shoulder for the width term: ``_other_shoulder``, lazily)
            if out is not None and _isfinite(sum(out)):
                prevs[side] = out
                self._remember_surface(side, out, m, o_e)
                # The segments held for a joint lost altogether (the held forearm turns with the upper arm: ``_arm``).
                self._blind[side], self._blind_e[side] = held_segments(
                    self._blind[side], self._blind_e[side], out, m, o_s, o_e, o_w, self._lu[side], self._lf[side],
                    self._cons)
                if (hold or others[1 - side] is not None) and m[o_s + 2] == m[o_s + 2]:
                    # The shoulder's depth measured: its offset from the hips' (and from the other shoulder, seen),
                    # a running mean (the depths read as an occluder approaches, just before the occlusion
                    # filter drops them, are its own).
                    if hold:
                        learn_offset(held_sh, side, out, hips, self._a_s)
                    if others[1 - side] is not None and self._pair_z[side][1] == 0.0:
                        learn_offset(held_ss, side, out, others[1 - side], self._a_s)
                held[side] = False
                chosen[side] = 0
                fallback[side] = lost[ke] > 0 and lost[ke + 1] > 0
            else:
                lost[ke], lost[ke + 1] = lost_e, lost_s
                out = prevs[side] if prevs[side] is not None else (_NAN,) * 9
            # (Nine item stores: about a third of the time of three slice assignments.)
            v[o_s], v[o_s + 1], v[o_s + 2], v[o_e], v[o_e + 1], v[o_e + 2], v[o_w], v[o_w + 1], v[o_w + 2] = out
        # (``np.fromiter`` over the 36 floats: about 0.2 µs less than ``np.array`` of the list.)
        return AKCResult(np.fromiter(v, _F64, _FLAT).reshape(_SHAPE), chosen, fallback, held, [_NAN, _NAN])
