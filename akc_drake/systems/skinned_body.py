"""The skinned operator in a SceneGraph: deformable geometries whose vertices follow the operator's pose.

:func:`register_skinned_body` registers one deformable geometry per clothing region
(:data:`~akc_drake.operator.skinned.REGIONS`, a tetrahedral shell each, with its colour and a render label)
with a SceneGraph; :class:`SkinnedBody` is the LeafSystem that turns the operator's joint angles into their
vertex positions (linear blend skinning, :mod:`akc_drake.core.skinning`) on SceneGraph's source
configuration port, and outputs the true landmarks (the rig's joint centres) in the world frame.
"""

from __future__ import annotations

import contextlib
import contextvars

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    GeometryConfigurationVector,
    GeometryInstance,
    IllustrationProperties,
    Mesh,
    PerceptionProperties,
    RenderLabel,
    Rgba,
)
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.operator.model import NUM_ARM_DOF
from akc_drake.operator.skinned import REGIONS, SkinnedOperator

#: Render labels of the regions (the primitive operator's bodies use the plant's body indices, < 100).
REGION_LABEL_BASE = 100
#: SceneGraph's resolution hint for the shells (only used by proximity queries, which we do not register).
_RESOLUTION_HINT = 0.05
#: The motion whose hand closure a SkinnedBody built without one follows (set by :func:`hands_follow`).
_HANDS_MOTION: contextvars.ContextVar = contextvars.ContextVar("akc_drake_skinned_hands", default=None)


@contextlib.contextmanager
def hands_follow(motion):
    """Within this block, a :class:`SkinnedBody` built without a ``motion`` closes its hands as ``motion``'s
    ``hand_closed`` says (for sources that build the body themselves, e.g. a whole-motion render of ``motion``)."""
    token = _HANDS_MOTION.set(motion)
    try:
        yield
    finally:
        _HANDS_MOTION.reset(token)


def register_skinned_body(
    scene_graph,
    body: SkinnedOperator,
    X_WO: RigidTransform | None = None,
    source_name: str = "skinned_operator",
    illustration: bool = False,
):
    """Register ``body``'s region shells with ``scene_graph`` (before the diagram is built).

    Args:
        scene_graph: a SceneGraph (with its renderer added, or added later).
        body: the skinned operator.
        X_WO: pose of the operator frame O in the world (default identity); the shells' vertices are
            given in the world frame.
        source_name: the geometry source's name.
        illustration: give the shells the illustration role too (for a visualizer such as Meshcat). Off by
            default: SceneGraph then recomputes every deformed shell once per role and frame, and the camera
            only needs perception (the illustration copy costs ~2 ms a frame that nothing reads).

    Returns:
        ``(source_id, {region: GeometryId})``.
    """
    source_id = scene_graph.RegisterSource(source_name)
    files = body.shell_files()
    ids = {}
    for name, path in files.items():
        instance = GeometryInstance(RigidTransform(), Mesh(str(path)), f"skinned_{name}")
        rgba = Rgba(*body.colors[name])
        props = PerceptionProperties()
        props.AddProperty("phong", "diffuse", rgba)
        region = body.piece_region[name]
        props.AddProperty("label", "id", RenderLabel(REGION_LABEL_BASE + REGIONS.index(region)))
        instance.set_perception_properties(props)
        if illustration:
            illus = IllustrationProperties()
            illus.AddProperty("phong", "diffuse", rgba)
            instance.set_illustration_properties(illus)
        ids[name] = scene_graph.RegisterDeformableGeometry(
            source_id, scene_graph.world_frame_id(), instance, _RESOLUTION_HINT
        )
    return source_id, ids


class SkinnedBody(LeafSystem):
    """Operator joint angles -> the skinned body's vertex positions and true landmarks (direct feedthrough).

    .. pydrake_system::

        name: SkinnedBody
        input_ports:
        - q
        output_ports:
        - geometry_configuration
        - landmarks_true_W

    ``q`` is ``[q_left, q_right]`` (10 angles, :func:`~akc_drake.operator.model.full_q` order);
    ``geometry_configuration`` a GeometryConfigurationVector for SceneGraph's source configuration port;
    ``landmarks_true_W`` the 12 true landmarks (row-major (12, 3)) in the world frame. With a ``motion`` that
    has a hand closure, the fingers follow it (at diagram time ``t``, the motion's closure at
    ``motion.start + t``, as the operator's trajectory source plays it): a closed hand is a pinch.
    """

    def __init__(self, body: SkinnedOperator, geometry_ids: dict, X_WO: RigidTransform | None = None, motion=None):
        """Args:
        body: the skinned operator.
        geometry_ids: ``{region: GeometryId}`` from :func:`register_skinned_body`.
        X_WO: pose of the operator frame O in the world (default identity).
        motion: the :class:`~akc_drake.operator.motions.OperatorMotion` whose ``hand_closed`` closes the hands
            (None, or a motion without one: the rig's relaxed hands; None inside :func:`hands_follow`: its
            motion); may be set later with :meth:`follow_hands`.
        """
        super().__init__()
        self.body = body
        self._motion = None
        self._rig = None
        self.follow_hands(motion if motion is not None else _HANDS_MOTION.get())
        self._ids = dict(geometry_ids)
        X = X_WO if X_WO is not None else RigidTransform()
        self._R = X.rotation().matrix()
        self._p = X.translation()
        self._buffer = np.empty_like(body.points_rest)
        self._q = self.DeclareVectorInputPort("q", 2 * NUM_ARM_DOF)
        self.DeclareAbstractOutputPort(
            "geometry_configuration",
            lambda: AbstractValue.Make(GeometryConfigurationVector()),
            self._calc_configuration,
            prerequisites_of_calc={self._q.ticket(), self.time_ticket()},
        )
        self.DeclareVectorOutputPort(
            "landmarks_true_W",
            3 * NUM_LANDMARKS,
            self._calc_landmarks,
            prerequisites_of_calc={self._q.ticket(), self.time_ticket()},
        )

    def follow_hands(self, motion) -> None:
        """Close the hands as ``motion``'s ``hand_closed`` says (None: relaxed hands)."""
        self._motion = motion if getattr(motion, "hand_closed", None) is not None else None

    def drive_rig(self, drive) -> None:
        """Pose the body from a clip's rig maps instead of ``q``: a
        :class:`~akc_drake.operator.rig_drive.RigDrive` on this body (its sample nearest to the diagram time;
        every bone moves: spine, clavicles, neck, head), and take the true landmarks from it. None: back to ``q``."""
        self._rig = drive

    def rig_configuration(self, t: float) -> dict[str, np.ndarray]:
        """``{region: (n, 3)}`` world-frame shell vertices of the rig-driven body at diagram time ``t``."""
        P = self.body.posed_points_from_maps(self._rig.maps_at(t), out=self._buffer)
        return self._regions_W(P)

    def closure(self, t: float):
        """``(2,)`` hand closure at diagram time ``t`` (None without a motion's closure)."""
        return None if self._motion is None else self._motion.closure([self._motion.start + float(t)])[0]

    def configuration(self, q: np.ndarray, closure=None) -> dict[str, np.ndarray]:
        """``{region: (n, 3)}`` world-frame shell vertices for the pose ``q`` and hand ``closure`` ``(2,)`` (None:
        relaxed hands); raises UserError if the pose is impossible."""
        q = self.body.check_q(q)[0]
        P = self.body.posed_points(q, out=self._buffer, closure=closure)
        return self._regions_W(P)

    def _regions_W(self, P: np.ndarray) -> dict[str, np.ndarray]:
        """The posed points ``P`` (operator frame) in the world, split into the shell regions."""
        if not np.array_equal(self._R, np.eye(3)) or np.any(self._p):
            P = P @ self._R.T + self._p
        return self.body.region_points(P)

    def _calc_configuration(self, context, output):
        value = GeometryConfigurationVector()
        if self._rig is not None:
            regions = self.rig_configuration(context.get_time())
        else:
            regions = self.configuration(self._q.Eval(context), self.closure(context.get_time()))
        for name, pts in regions.items():
            value.set_value(self._ids[name], pts.ravel())
        output.set_value(value)

    def _calc_landmarks(self, context, output):
        if self._rig is not None:
            lm = self._rig.landmarks_O[self._rig.index(context.get_time())]
        else:
            lm = self.body.landmarks_O(self._q.Eval(context)[None])[0]
        output.SetFromVector((lm @ self._R.T + self._p).ravel())
