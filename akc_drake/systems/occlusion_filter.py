"""Stage S3a: the occlusion filter (paper §II-C) as a Drake system (stateless, or holding each landmark's last
accepted position at the camera period)."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem, OutputPort, ValueProducer

from akc_drake.core.landmark_tracking import filter_period
from akc_drake.core.occlusion import (
    BACKGROUND_M,
    DEFAULT_PROXIMITY,
    DEFAULT_VISIBILITY_THRESHOLD,
    HAND_REACH_M,
    check_parameters,
    occlusion_filter,
)
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.systems import timing

_J = NUM_LANDMARKS


class OcclusionFilter(LeafSystem):
    """Rejects low-visibility landmarks and drops the depth of proximal joints hidden by distal ones, and of
    landmarks read on the background behind the body (``background_m``) or a hip read on a hand in front of it
    (``hand_reach_m``).

    A direct-feedthrough wrapper of :func:`akc_drake.core.occlusion.occlusion_filter`. Without ``period_s``
    it has no state and each output is computed from the current inputs (``x``, ``y`` of a dropped depth kept
    as deprojected, at the occluder's depth). With ``period_s`` (as :func:`akc_drake.diagrams` builds it) it
    holds each landmark's last accepted position (discrete state, 36, row-major ``(12, 3)``, NaN: none yet),
    updated at the camera period with the filter's stage offset, and puts a dropped depth's ``x``, ``y`` on
    its pixel's ray at that depth (``hold_rays``; the module docstring of :mod:`akc_drake.core.occlusion`).

    .. pydrake_system::

        name: OcclusionFilter
        input_ports:
        - landmarks_C
        - visibility (optional)
        - pixels (optional)
        output_ports:
        - landmarks_C_accepted
        - rejected

    ``landmarks_C`` and ``landmarks_C_accepted`` are the ``(12, 3)`` camera-frame landmarks flattened
    row-major (36, NaN where missing); ``visibility`` is 12 numbers in [0, 1]; ``pixels`` is the
    ``(12, 2)`` pixel array flattened row-major (24). ``rejected`` is 24 flags (0/1): 12 "landmark
    rejected" (visibility below threshold) followed by 12 "depth dropped" (proximity or background check).
    An unconnected ``visibility`` counts as fully visible and unconnected ``pixels`` as unknown
    (no proximity check), so ground-truth or recorded 3D landmarks can be fed in directly.

    Args:
        image_width: image width in pixels (the proximity radius is a fraction of it).
        visibility_threshold: landmarks with visibility below this are rejected (paper: 0.7).
        proximity: proximity radius as a fraction of the image width (paper: 0.05).
        period_s: camera period, seconds: hold the last accepted positions (None: stateless).
        hold_rays: with ``period_s``, move a dropped depth's ``x``, ``y`` along its ray (False: the paper's
            filter; the state then stays NaN).
        stage_offset_s: the per-stage offset of :func:`akc_drake.systems.timing.stage_offset`.
        background_m: drop a depth read farther than this behind every accepted neighbour on the body (ours;
            None: off, as in the paper's filter).
        hand_reach_m: drop a hip's depth read on a hand in front of it, the hand within this of its ray (ours;
            None: off, as in the paper's filter; :func:`~akc_drake.core.occlusion.occlusion_filter`).

    Raises:
        ValueError: a parameter is out of range (the message names it).
    """

    def __init__(
        self,
        image_width: float = 640,
        *,
        visibility_threshold: float = DEFAULT_VISIBILITY_THRESHOLD,
        proximity: float = DEFAULT_PROXIMITY,
        period_s: float | None = None,
        hold_rays: bool = True,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
        background_m: float | None = BACKGROUND_M,
        hand_reach_m: float | None = HAND_REACH_M,
    ):
        super().__init__()
        check_parameters(image_width, visibility_threshold, proximity, background_m, hand_reach_m)
        self.image_width = float(image_width)
        self.visibility_threshold = float(visibility_threshold)
        self.proximity = float(proximity)
        self.hold_rays = bool(hold_rays)
        self.background_m = None if background_m is None else float(background_m)
        self.hand_reach_m = None if hand_reach_m is None else float(hand_reach_m)
        self._u_landmarks = self.DeclareVectorInputPort("landmarks_C", 3 * _J)
        self._u_visibility = self.DeclareVectorInputPort("visibility", _J)
        self._u_pixels = self.DeclareVectorInputPort("pixels", 2 * _J)
        ports = (self._u_landmarks, self._u_visibility, self._u_pixels)
        deps = {self.input_port_ticket(p.get_index()) for p in ports}
        self._x_held = None
        if period_s is not None:
            period_s = filter_period(period_s)  # (checked: a positive number of seconds)
            self._x_held = self.DeclareDiscreteState(BasicVector(np.full(3 * _J, np.nan)))
            deps.add(self.discrete_state_ticket(self._x_held))
            self.DeclarePeriodicDiscreteUpdateEvent(
                period_sec=period_s, offset_sec=timing.stage_offset("filter", stage_offset_s),
                update=self._update,
            )
        # One run of the filter per input and state: both outputs and the update read it.
        self._result = self.DeclareCacheEntry(
            "occlusion filter result",
            ValueProducer(allocate=AbstractValue.Make((None, None, None)).Clone, calc=self._calc_result), deps,
        )
        ticket = {self._result.ticket()}
        self.DeclareVectorOutputPort(
            "landmarks_C_accepted", 3 * _J, self._calc_accepted, prerequisites_of_calc=ticket
        )
        self.DeclareVectorOutputPort("rejected", 2 * _J, self._calc_rejected, prerequisites_of_calc=ticket)

    def _run(self, context, held=None):
        landmarks = self._u_landmarks.Eval(context).reshape(_J, 3)
        if self._u_visibility.HasValue(context):
            visibility = self._u_visibility.Eval(context)
        else:
            visibility = np.ones(_J)
        if self._u_pixels.HasValue(context):
            pixels = self._u_pixels.Eval(context).reshape(_J, 2)
        else:
            pixels = np.full((_J, 2), np.nan)
        return occlusion_filter(
            landmarks,
            pixels,
            visibility,
            self.image_width,
            visibility_threshold=self.visibility_threshold,
            proximity=self.proximity,
            hold_rays=self.hold_rays,
            held=held,
            background_m=self.background_m,
            hand_reach_m=self.hand_reach_m,
        )

    def _held(self, context) -> np.ndarray | None:
        """A ``(12, 3)`` copy of the held positions (None when stateless)."""
        if self._x_held is None:
            return None
        return np.array(context.get_discrete_state(self._x_held).get_value(), dtype=np.float64).reshape(_J, 3)

    def _calc_result(self, context, value) -> None:
        """The cache entry: ``(accepted, info, held)``, ``held`` the state after this frame (None: stateless)."""
        held = self._held(context)
        accepted, info = self._run(context, held)
        value.set_value((accepted, info, held))

    def _update(self, context, discrete_state) -> None:
        held = self._result.Eval(context)[2]
        discrete_state.get_mutable_vector(self._x_held).SetFromVector(held.reshape(-1))

    def _calc_accepted(self, context, output) -> None:
        output.SetFromVector(self._result.Eval(context)[0].reshape(-1))

    def _calc_rejected(self, context, output) -> None:
        info = self._result.Eval(context)[1]
        output.SetFromVector(np.concatenate((info.rejected, info.depth_dropped)).astype(np.float64))


def AddOcclusionFilter(
    builder: DiagramBuilder,
    landmarks_C: OutputPort | None = None,
    visibility: OutputPort | None = None,
    pixels: OutputPort | None = None,
    *,
    image_width: float = 640,
    visibility_threshold: float = DEFAULT_VISIBILITY_THRESHOLD,
    proximity: float = DEFAULT_PROXIMITY,
    period_s: float | None = None,
    hold_rays: bool = True,
    background_m: float | None = BACKGROUND_M,
    hand_reach_m: float | None = HAND_REACH_M,
    name: str = "OcclusionFilter",
) -> OcclusionFilter:
    """Add an :class:`OcclusionFilter` to ``builder`` and connect the given source ports.

    Args:
        builder: the diagram builder.
        landmarks_C, visibility, pixels: output ports to connect to the inputs of the same name
            (None leaves that input unconnected).
        image_width, visibility_threshold, proximity, period_s, hold_rays, background_m, hand_reach_m: as for
            :class:`OcclusionFilter`.
        name: the system's name.

    Returns:
        The added system.
    """
    system = builder.AddSystem(
        OcclusionFilter(image_width, visibility_threshold=visibility_threshold, proximity=proximity,
                        period_s=period_s, hold_rays=hold_rays, background_m=background_m,
                        hand_reach_m=hand_reach_m)
    )
    system.set_name(name)
    for port, input_name in ((landmarks_C, "landmarks_C"), (visibility, "visibility"), (pixels, "pixels")):
        if port is not None:
            builder.Connect(port, system.GetInputPort(input_name))
    return system
