"""Stage S3a: the occlusion filter (paper §II-C) as a stateless Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import DiagramBuilder, LeafSystem, OutputPort

from akc_drake.core.occlusion import (
    DEFAULT_PROXIMITY,
    DEFAULT_VISIBILITY_THRESHOLD,
    check_parameters,
    occlusion_filter,
)
from akc_drake.core.skeleton import NUM_LANDMARKS

_J = NUM_LANDMARKS


class OcclusionFilter(LeafSystem):
    """Rejects low-visibility landmarks and drops the depth of proximal joints hidden by distal ones.

    A direct-feedthrough wrapper of :func:`akc_drake.core.occlusion.occlusion_filter`: no state,
    each output is computed from the current inputs.

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
    rejected" (visibility below threshold) followed by 12 "depth dropped" (proximity check).
    An unconnected ``visibility`` counts as fully visible and unconnected ``pixels`` as unknown
    (no proximity check), so ground-truth or recorded 3D landmarks can be fed in directly.

    Args:
        image_width: image width in pixels (the proximity radius is a fraction of it).
        visibility_threshold: landmarks with visibility below this are rejected (paper: 0.7).
        proximity: proximity radius as a fraction of the image width (paper: 0.05).

    Raises:
        ValueError: a parameter is out of range (the message names it).
    """

    def __init__(
        self,
        image_width: float = 640,
        *,
        visibility_threshold: float = DEFAULT_VISIBILITY_THRESHOLD,
        proximity: float = DEFAULT_PROXIMITY,
    ):
        super().__init__()
        check_parameters(image_width, visibility_threshold, proximity)
        self.image_width = float(image_width)
        self.visibility_threshold = float(visibility_threshold)
        self.proximity = float(proximity)
        self._u_landmarks = self.DeclareVectorInputPort("landmarks_C", 3 * _J)
        self._u_visibility = self.DeclareVectorInputPort("visibility", _J)
        self._u_pixels = self.DeclareVectorInputPort("pixels", 2 * _J)
        ports = (self._u_landmarks, self._u_visibility, self._u_pixels)
        inputs = {self.input_port_ticket(p.get_index()) for p in ports}
        self.DeclareVectorOutputPort(
            "landmarks_C_accepted", 3 * _J, self._calc_accepted, prerequisites_of_calc=inputs
        )
        self.DeclareVectorOutputPort("rejected", 2 * _J, self._calc_rejected, prerequisites_of_calc=inputs)

    def _run(self, context):
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
        )

    def _calc_accepted(self, context, output) -> None:
        accepted, _ = self._run(context)
        output.SetFromVector(accepted.reshape(-1))

    def _calc_rejected(self, context, output) -> None:
        _, info = self._run(context)
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
    name: str = "OcclusionFilter",
) -> OcclusionFilter:
    """Add an :class:`OcclusionFilter` to ``builder`` and connect the given source ports.

    Args:
        builder: the diagram builder.
        landmarks_C, visibility, pixels: output ports to connect to the inputs of the same name
            (None leaves that input unconnected).
        image_width, visibility_threshold, proximity: as for :class:`OcclusionFilter`.
        name: the system's name.

    Returns:
        The added system.
    """
    system = builder.AddSystem(
        OcclusionFilter(image_width, visibility_threshold=visibility_threshold, proximity=proximity)
    )
    system.set_name(name)
    for port, input_name in ((landmarks_C, "landmarks_C"), (visibility, "visibility"), (pixels, "pixels")):
        if port is not None:
            builder.Connect(port, system.GetInputPort(input_name))
    return system
