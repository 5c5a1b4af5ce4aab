"""Your own corrector as a Drake LeafSystem, in the mocap diagram in place of stage S4.

The pipeline is built from the same helpers :func:`akc_drake.diagrams.build_mocap_diagram` uses: the source (S1 +
S2) and stage S3 with no corrector, then your system on the filter's output, then the stage loggers, so that
``simulate()`` returns the per-frame log of every stage, yours as ``corrected``::

    .venv/bin/python examples/own_leaf_system.py          # one cycle of Motion I, rendered; prints the RMSEs

The system here wraps ``examples/segment_lengths.py`` (the naive length projection). It follows the diagram's
conventions (:mod:`akc_drake.systems.timing`): a periodic update at the camera period, offset to the corrector's
stage so that it reads the filter's output of the same frame, and its output is its state (no direct feedthrough).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from akc_drake import diagrams
from akc_drake.config import PipelineConfig
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.evaluation.methods import load_corrector
from akc_drake.systems import timing

_HERE = Path(__file__).resolve().parent


def _segment_lengths():
    """The factory of ``segment_lengths.py``, loaded as ``evaluate --add-corrector`` loads it."""
    return load_corrector(f"{_HERE / 'segment_lengths.py'}:SegmentLengths")


class SegmentLengthsSystem(LeafSystem):
    """Stage S4 replaced: ``landmarks_C`` (36, the filter's pose) -> ``landmarks_C_corrected`` (36).

    State: the last corrected pose (discrete, 36; NaN before the first frame).
    """

    def __init__(self, dims, filter_kind: str, rate_hz: float, stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S):
        super().__init__()
        self._corrector = _segment_lengths()(dims, filter_kind, 1.0 / rate_hz)
        self._u = self.DeclareVectorInputPort("landmarks_C", 3 * NUM_LANDMARKS)
        self._x = self.DeclareDiscreteState(BasicVector(np.full(3 * NUM_LANDMARKS, np.nan)))
        self.DeclareStateOutputPort("landmarks_C_corrected", self._x)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=1.0 / rate_hz, offset_sec=timing.stage_offset("corrector", stage_offset_s), update=self._update
        )

    def _update(self, context, discrete_state):
        pose = self._u.Eval(context).reshape(NUM_LANDMARKS, 3)
        discrete_state.get_mutable_vector(self._x).SetFromVector(self._corrector.correct(pose).reshape(-1))


def build(cfg: PipelineConfig) -> diagrams.MocapDiagram:
    """The mocap diagram of ``cfg`` with :class:`SegmentLengthsSystem` as its corrector."""
    cfg = dataclasses.replace(cfg, corrector="none")
    dims = diagrams.resolve_dims(cfg)
    builder = DiagramBuilder()
    source = diagrams.AddMeasurementSource(builder, cfg)
    ports = diagrams.AddMocapPipeline(builder, cfg, dims, source)
    mine = builder.AddSystem(SegmentLengthsSystem(dims, cfg.filter, cfg.camera.rate_hz, cfg.stage_offset_s))
    mine.set_name("SegmentLengthsSystem")
    builder.Connect(ports.estimated, mine.get_input_port())
    ports = dataclasses.replace(ports, corrected=mine.get_output_port(),
                                systems={**ports.systems, "corrector": mine})
    loggers = diagrams.AddStageLoggers(builder, ports, diagrams.camera_period(cfg))
    diagram = builder.Build()
    diagram.set_name("mocap_with_my_corrector")
    return diagrams.MocapDiagram(diagram, cfg, dims, ports, loggers, source.get("num_frames"),
                                 source.get("intrinsics"))


def main() -> None:
    from akc_drake.core.metrics import joint_errors
    from akc_drake.core.skeleton import ARM_JOINTS

    mocap = build(PipelineConfig(motion="I", cycles=1, filter="KF"))
    log, wall = mocap.simulate(progress=True)
    print(f"{log.corrected.shape[0]} frames in {wall:.1f} s")
    for stage in ("estimated", "corrected"):
        err = joint_errors(getattr(log, stage), log.truth, ARM_JOINTS)
        print(stage, {j: [round(v, 2) for v in e["rmse_cm"].values()] for j, e in err.items()})


if __name__ == "__main__":
    main()
