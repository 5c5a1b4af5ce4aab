"""Acclaim skeleton (ASF) and motion (AMC) files, as used by the CMU motion-capture database.

An ASF file describes the skeleton in a rest pose: the root (``:root``), one block per bone
(``:bonedata``: id, name, a unit ``direction`` in the global rest frame, ``length``,
``axis ax ay az ORDER`` giving the bone's local coordinate system, ``dof`` and ``limits``) and the
parent/child relations (``:hierarchy``). ``:units`` gives the length scale (CMU: ``length 0.45``, the
data being in inches: metres = value / 0.45 * 0.0254) and the angle unit. An AMC file lists, frame by
frame, each bone's dof values in its ``dof`` order.

Forward kinematics (the Acclaim definition, written with column vectors):

* ``C`` is the bone's axis rotation, built from the three ``axis`` angles (about x, y, z) in the listed
  order, the first listed applied first: ``axis ... XYZ`` gives ``C = Rz @ Ry @ Rx``.
* ``M`` is the bone's motion rotation built the same way from its rotation dofs in ``dof`` order
  (``dof rx ry rz`` gives ``M = Rz @ Ry @ Rx``).
* The bone's global rotation is ``G = G_parent @ C @ M @ C^-1`` (the spec's row-vector
  ``L = C^-1 M C``), and its distal end is ``end = start + G @ (length * direction)`` (plus any
  translation dofs, expressed in the axis frame C). ``start`` is the parent's end (the root's
  position for children of the root).
* The root uses ``orientation`` (with ``:root axis``) as its C and the AMC values in ``:root order``;
  translation dofs give the root's position (absolute, replacing ``:root position`` on that axis).

Errors in a file raise :class:`akc_drake.errors.UserError` whose message starts with ``file:line:``.
"""

from akc_drake.operator.asf_amc.format import format_amc, format_asf, write_amc, write_asf
from akc_drake.operator.asf_amc.model import (
    BONE_DOFS,
    ROOT_DOFS,
    ROTATION_DOFS,
    TRANSLATION_DOFS,
    AMCMotion,
    ASFBone,
    ASFSkeleton,
)
from akc_drake.operator.asf_amc.parse import parse_amc, parse_asf, read_amc, read_asf

__all__ = [
    "BONE_DOFS",
    "ROOT_DOFS",
    "ROTATION_DOFS",
    "TRANSLATION_DOFS",
    "AMCMotion",
    "ASFBone",
    "ASFSkeleton",
    "format_amc",
    "format_asf",
    "parse_amc",
    "parse_asf",
    "read_amc",
    "read_asf",
    "write_amc",
    "write_asf",
]
