"""Opening what a run reads: the source named by ``config.source``, its detector and the body dimensions."""

from __future__ import annotations

from dataclasses import dataclass, field

from akc_drake.errors import UserError
from akc_drake.pipeline.runner import TimedDetector


@dataclass
class PipelineInputs:
    """What a run needs to build the diagram on ``config.source``.

    Attributes:
        config: the pipeline configuration (camera size and rate set from a real source).
        frame_source: the opened real source, or None for ``sim``.
        detector: a :class:`~akc_drake.pipeline.runner.TimedDetector` around MediaPipe for a real source,
            around the simulated detector (as the extractor's default) for ``sim``.
        motion: the operator motion for ``sim``.
        dims: body dimensions (None: the diagram's default, the simulated operator's).
        dims_origin: where ``dims`` come from, for the report.
        notes: remarks for the user (printed by the command).
    """

    config: object
    frame_source: object = None
    detector: TimedDetector | None = None
    motion: object = None
    dims: object = None
    dims_origin: str = "simulated operator"
    notes: list[str] = field(default_factory=list)

    def close(self) -> None:
        """Release the source and the detector (MediaPipe's graph, the camera)."""
        for obj in (self.detector, self.frame_source):
            close = getattr(obj, "close", None)
            if callable(close):
                try:
                    close()
                except Exception:  # closing must never hide the run's own outcome
                    pass


def source_kind(spec: str) -> str:
    """``"sim"``, ``"recording"``, ``"bag"``, ``"realsense"`` or ``"video"`` from a ``--source`` spec."""
    return spec.strip().split(":", 1)[0].lower()


def open_inputs(
    cfg,
    *,
    dims_path: str | None = None,
    depth_m: float | None = None,
    pose_model: str | None = None,
    seconds: float | None = None,
    skeleton: str | None = None,
    motion=None,
    default_real_dims: bool = True,
) -> PipelineInputs:
    """Open ``cfg.source`` (and MediaPipe for a real one), load ``dims_path``; user mistakes raise UserError.

    Args:
        cfg: the :class:`~akc_drake.config.PipelineConfig`; a real source's size and rate are copied into it.
        dims_path: calibrated body dimensions (``--dims FILE.json``), or None.
        depth_m: constant depth for a ``video:FILE`` source (``--depth``).
        pose_model: MediaPipe's ``.task`` model (``--pose-model``), or None for the packaged one.
        seconds: how long a live camera streams (``--seconds``), or None.
        skeleton: the ASF skeleton of an AMC ``cfg.motion`` (default: ``cfg.skeleton``).
        motion: the motion to render for ``sim`` (default: ``cfg.motion``).
        default_real_dims: without ``dims_path``, give a real source the paper's manual arm lengths.
    """
    from akc_drake.io.sources import open_source
    from akc_drake.operator.retarget import motion_from_spec

    dims = None
    if dims_path:
        from akc_drake.core.calibration import load_dims

        dims = load_dims(dims_path)
    inputs = PipelineInputs(config=cfg, dims=dims, dims_origin=str(dims_path) if dims is not None else "")
    spec = cfg.source
    kind = source_kind(spec)
    if kind == "sim" and ":" not in spec:
        if depth_m is not None:
            raise UserError("--depth applies to a video:FILE source only")
        if motion is None:
            motion = motion_from_spec(
                cfg.motion,
                cycles=cfg.cycles,
                seed=cfg.seed,
                skeleton=skeleton or cfg.skeleton or None,
                rate_hz=cfg.camera.rate_hz,
                names=cfg.joint_names or None,
            )
        inputs.motion = motion
        from akc_drake.systems.depth_camera_source import make_detector

        inputs.detector = TimedDetector(make_detector(cfg.detector, cfg.seed, pose_model))
        if dims is None:
            inputs.dims_origin = "simulated operator"
        return inputs
    opts = {"depth_m": depth_m}
    if kind == "realsense":
        # The camera streams at its own fps; the pipeline pulls the newest frame at the configured rate.
        opts = {"rate_hz": cfg.camera.rate_hz, "seconds": seconds}
    source = open_source(spec, **opts)
    inputs.frame_source = source
    try:
        K = source.intrinsics
        cfg.camera.width, cfg.camera.height, cfg.camera.rate_hz = (
            int(K.width),
            int(K.height),
            float(source.rate_hz),
        )
        from akc_drake.io.mediapipe_detector import MediaPipeDetector

        inputs.detector = TimedDetector(MediaPipeDetector(model_path=pose_model))
    except BaseException:
        inputs.close()
        raise
    if dims is None and default_real_dims:
        from akc_drake.core.skeleton import BodyDimensions

        inputs.dims = BodyDimensions.paper_manual()
        inputs.dims_origin = "paper manual (no --dims)"
        inputs.notes.append("no --dims given: using the paper's manual arm lengths (run 'akc-drake calibrate')")
    return inputs
