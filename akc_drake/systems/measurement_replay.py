"""Replays recorded stage-S2 measurements (landmarks, visibility, pixels) into a diagram, without rendering."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.systems.timing import stage_offset


class MeasurementReplay(LeafSystem):
    """Outputs frame ``k`` of recorded measurements from the extractor's sample time of frame ``k`` on.

    .. pydrake_system::

        name: MeasurementReplay
        output_ports:
        - landmarks_C
        - visibility
        - pixels
        - landmarks_true_C
        - frame_index

    It stands in for DepthCameraSource + LandmarkExtractor, with the same output ports and timing, so the
    rest of the pipeline can be run many times on one rendering (the evaluation, the benchmarks and the demo's
    corrector comparison). Before the first frame every output is NaN; after the last it holds the last frame.

    Args:
        landmarks_C: ``(T, 12, 3)`` measured landmarks in the camera frame (NaN where missing).
        visibility: ``(T, 12)``.
        pixels: ``(T, 12, 2)``.
        truth_C: ``(T, 12, 3)`` ground truth, or None (NaN output).
        period_s: the camera period.
        stage_offset_s: the per-stage offset (see :mod:`akc_drake.systems.timing`).
    """

    def __init__(self, landmarks_C, visibility, pixels, truth_C=None, period_s: float = 0.1,
                 stage_offset_s: float = 1e-3):
        super().__init__()
        L = np.asarray(landmarks_C, dtype=float)
        T = L.shape[0]
        if L.shape != (T, NUM_LANDMARKS, 3):
            raise ValueError(f"landmarks_C must have shape (T, {NUM_LANDMARKS}, 3), got {L.shape}")
        V = np.asarray(visibility, dtype=float).reshape(T, NUM_LANDMARKS)
        P = np.asarray(pixels, dtype=float).reshape(T, NUM_LANDMARKS, 2)
        G = np.full_like(L, np.nan) if truth_C is None else np.asarray(truth_C, dtype=float).reshape(L.shape)
        self._rows = np.concatenate(
            [L.reshape(T, -1), V, P.reshape(T, -1), G.reshape(T, -1)], axis=1
        )
        self._num_frames = T
        n = self._rows.shape[1]
        nan_row = np.full(n + 1, np.nan)
        nan_row[-1] = -1.0
        self._state = self.DeclareDiscreteState(nan_row)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, stage_offset("extractor", stage_offset_s), self._update)
        sizes = (3 * NUM_LANDMARKS, NUM_LANDMARKS, 2 * NUM_LANDMARKS, 3 * NUM_LANDMARKS, 1)
        names = ("landmarks_C", "visibility", "pixels", "landmarks_true_C", "frame_index")
        start = 0
        for name, size in zip(names, sizes, strict=True):
            self.DeclareVectorOutputPort(name, size, self._make_calc(start, size), prerequisites_of_calc={
                self.discrete_state_ticket(self._state)})
            start += size

    @property
    def num_frames(self) -> int:
        return self._num_frames

    def _make_calc(self, start: int, size: int):
        def calc(context, output: BasicVector):
            output.SetFromVector(context.get_discrete_state(self._state).value()[start : start + size])

        return calc

    def _update(self, context, discrete_state):
        k = int(discrete_state.get_vector(self._state).value()[-1]) + 1
        k = min(k, self._num_frames - 1)
        row = np.empty(self._rows.shape[1] + 1)
        row[:-1] = self._rows[k]
        row[-1] = k
        discrete_state.get_mutable_vector(self._state).SetFromVector(row)
