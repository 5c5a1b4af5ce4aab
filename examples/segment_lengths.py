r"""A corrector of your own for ``akc-drake evaluate --add-corrector``: the naive length projection.

Each arm is rebuilt from the filter's shoulder outwards, every segment put back at its calibrated length along the
direction the filter gives it. It is the simplest corrector that keeps the lengths exact, a baseline for AKC and
AKC+ (which choose where a segment's error goes)::

    akc-drake evaluate --motion-dir data/mocap --protocol ours \
        --add-corrector LEN=examples/segment_lengths.py:SegmentLengths

runs ``LEN(KF)`` and ``LEN(EKF)`` beside the default methods, with the same tables, worst increases and lost-joint
figures as AKC+. The interface (:func:`akc_drake.evaluation.methods.load_corrector`): the factory (here the class)
is called with the calibrated body dimensions, the filter's name and the frame period; ``correct`` is called each
frame with the filter's pose, the occlusion filter's measurement and the filter's variance (``(12, 3)`` each,
camera frame, metres, NaN where missing) and returns the corrected ``(12, 3)`` pose; ``reset`` starts a session.
"""

import numpy as np

from akc_drake.core.skeleton import INDEX

_ARMS = (("left", "LUA", "LLA"), ("right", "RUA", "RLA"))


class SegmentLengths:
    """The filter's arms with the calibrated segment lengths, along the filter's segment directions."""

    def __init__(self, dims, filter_kind, period_s):
        self._arms = [(INDEX[f"{side}_shoulder"], INDEX[f"{side}_elbow"], INDEX[f"{side}_wrist"],
                       getattr(dims, upper), getattr(dims, lower)) for side, upper, lower in _ARMS]

    def reset(self):
        """Nothing is kept from one frame to the next."""

    def correct(self, pose, measured=None, variance=None):
        out = np.array(pose, dtype=float)
        for s, e, w, upper, lower in self._arms:
            for a, b, length in ((s, e, upper), (e, w, lower)):
                d = np.asarray(pose[b], dtype=float) - np.asarray(pose[a], dtype=float)
                n = np.linalg.norm(d)
                if np.isfinite(n) and n > 0.0:
                    out[b] = out[a] + d * (length / n)  # (out[a]: the joint before, already put back)
        return out
