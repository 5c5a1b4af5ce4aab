"""The gripper channel of stage S5: the hand's thumb-index distance -> the parallel gripper's finger opening."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from akc_drake.core.gripper import GripperHysteresis, aperture_from_closure
from akc_drake.core.skeleton import SIDES


class HandApertureSource(LeafSystem):
    """The simulated operator's thumb-index distance per hand, sampled at the camera rate.

    .. pydrake_system::

        name: HandApertureSource
        output_ports:
        - thumb_index_m

    The simulated operator has no fingers (its 12 pose landmarks end at the knuckles), so this channel stands
    for a hand detector (MediaPipe Hands' thumb tip and index tip on a real camera): the motion's hand closure
    (:attr:`~akc_drake.operator.motions.OperatorMotion.hand_closed`) turned into a distance
    (:func:`~akc_drake.core.gripper.aperture_from_closure`) with 4 mm of seeded Gaussian noise; NaN in frames
    the ``dropout`` mask blanks (the person lost). ``thumb_index_m`` is ``[left, right]`` in metres, held
    between camera frames. With ``apertures`` (a hand detector's measurements per frame, e.g. MediaPipe Hands on
    the rendered frames, :class:`~akc_drake.io.hand_detector.HandDetector`) it replays those instead.

    Args:
        motion: the :class:`~akc_drake.operator.motions.OperatorMotion`.
        period_s: camera period; frame ``k`` is the motion at ``motion.start + k * period_s``.
        seed: noise seed; noise_m: noise standard deviation.
        dropout: optional ``(frames,)`` bool mask of blanked frames.
        apertures: optional ``(frames, 2)`` measured thumb-index distances (NaN: hand not found) to replay.
    """

    def __init__(
        self, motion, period_s: float, *, seed: int = 0, noise_m: float = 0.004, dropout=None, apertures=None
    ):
        super().__init__()
        times = motion.frame_times(1.0 / period_s)
        if apertures is not None:
            self._values = np.array(apertures, dtype=float).reshape(-1, 2)
            if len(self._values) == 0:
                raise ValueError("HandApertureSource: apertures has no frames")
            times = times[: len(self._values)]
        else:
            rng = np.random.default_rng([int(seed), 0x4A7D])
            self._values = aperture_from_closure(motion.closure(times), rng, noise_m)
        if dropout is not None:
            mask = np.asarray(dropout, dtype=bool)[: len(times)]
            self._values[np.flatnonzero(mask)] = np.nan
        # Frame 0 from the start; each update moves to the next frame (counted, so a run may start at any time).
        self._state = self.DeclareDiscreteState(self._values[0])
        self._frame = self.DeclareDiscreteState(np.array([-1.0]))  # the first update (at the start) shows frame 0
        self.DeclareStateOutputPort("thumb_index_m", self._state)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, discrete_state) -> None:
        k = int(context.get_discrete_state(self._frame).get_value()[0]) + 1
        k = min(k, len(self._values) - 1)
        discrete_state.get_mutable_vector(self._frame).SetFromVector([k])
        discrete_state.get_mutable_vector(self._state).SetFromVector(self._values[k])


class GripperCommand(LeafSystem):
    """Pinch -> gripper, per hand, with hysteresis (:class:`~akc_drake.core.gripper.GripperHysteresis`).

    .. pydrake_system::

        name: GripperCommand
        input_ports:
        - thumb_index_m
        output_ports:
        - left_opening
        - right_opening
        - closed

    ``thumb_index_m`` is ``[left, right]`` (metres, NaN: unknown, the state is kept). ``*_opening`` is the finger
    opening to command (metres, 1 value for both fingers of that gripper); ``closed`` is ``[left, right]``,
    1.0 when closed. State: ``closed`` (2), updated once per camera frame at ``offset_s``.

    Args:
        period_s: camera period; offset_s: update offset after the camera's sample time.
        hysteresis: the thresholds and finger positions.
    """

    def __init__(self, period_s: float, offset_s: float = 0.0, hysteresis: GripperHysteresis | None = None):
        super().__init__()
        self._h = hysteresis or GripperHysteresis()
        self._input = self.DeclareVectorInputPort("thumb_index_m", 2)
        self._closed = self.DeclareDiscreteState(np.zeros(2))
        for k, side in enumerate(SIDES):
            self.DeclareVectorOutputPort(
                f"{side}_opening", 1, lambda ctx, out, k=k: self._opening(ctx, out, k), {self.all_state_ticket()}
            )
        self.DeclareStateOutputPort("closed", self._closed)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, offset_s, self._update)

    def _opening(self, context, output, k: int) -> None:
        closed = context.get_discrete_state(self._closed).get_value()[k] > 0.5
        output.SetFromVector([self._h.opening(closed)])

    def _update(self, context, discrete_state) -> None:
        d = self._input.Eval(context)
        closed = context.get_discrete_state(self._closed).get_value()
        new = [float(self._h.step(bool(c > 0.5), float(a))) for c, a in zip(closed, d, strict=True)]
        discrete_state.get_mutable_vector(self._closed).SetFromVector(new)
