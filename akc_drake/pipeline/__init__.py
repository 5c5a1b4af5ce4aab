"""Running a source through the mocap or teleop diagram: the layer between the diagram builders and the CLI.

- :mod:`akc_drake.pipeline.inputs`: open a source (``sim``, recording, bag, RealSense, video) and its detector;
- :mod:`akc_drake.pipeline.runner`: advance the diagram frame by frame, stage by stage, timing each stage
  (:func:`run_pipeline`), ending cleanly on a camera failure with the frames done so far;
- :mod:`akc_drake.pipeline.summary`: the run's summary (the ``akc-drake run --json`` keys) and ``poses.npz``.

The command modules (``akc_drake.commands.run``, ``calibrate``) only parse arguments and print.
"""

from akc_drake.pipeline.inputs import PipelineInputs, open_inputs
from akc_drake.pipeline.runner import LATENCY_STAGES, RunResult, TimedDetector, build_and_run, run_pipeline
from akc_drake.pipeline.summary import latency_summary, person_mask, run_summary, save_poses, summarize

__all__ = [
    "LATENCY_STAGES",
    "PipelineInputs",
    "RunResult",
    "TimedDetector",
    "build_and_run",
    "latency_summary",
    "open_inputs",
    "person_mask",
    "run_pipeline",
    "run_summary",
    "save_poses",
    "summarize",
]
