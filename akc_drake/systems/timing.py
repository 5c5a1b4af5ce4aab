"""When each stage of the pipeline runs.

Every sampled stage updates periodically at the camera period. Drake computes all discrete updates
that fall at the same instant from the same (pre-update) context, so a chain of stages sampled at the
same instant would add one camera period of latency per stage. Instead each stage is offset by a small
``stage_offset`` after the one before it: the camera frame taken at ``t_k`` is extracted at
``t_k + 1 * offset``, filtered at ``t_k + 2 * offset``, corrected at ``t_k + 3 * offset`` and mapped to
control frames at ``t_k + 4 * offset``. The offsets model the pipeline's own processing latency (a few
milliseconds), keep the chain deterministic, and keep every output a pure function of state.

The occlusion filter is direct-feedthrough: its outputs follow the extractor's within the same instant. Built
with a period, it also records each landmark's last accepted position at the filter's instant, from the same
inputs the filter reads then; the record changes none of frame ``k``'s outputs (a row recorded is one the
hold does not move).
"""

DEFAULT_CAMERA_RATE_HZ = 10.0
DEFAULT_STAGE_OFFSET_S = 1e-3

#: Stage index of each sampled stage (its update time is ``t_k + index * stage_offset``).
STAGE_INDEX = {
    "source": 0,
    "extractor": 1,
    "filter": 2,
    "corrector": 3,
    "mapper": 4,
}


def stage_offset(stage: str, stage_offset_s: float = DEFAULT_STAGE_OFFSET_S) -> float:
    """Offset in seconds of ``stage``'s periodic update after the camera's sample time."""
    return STAGE_INDEX[stage] * stage_offset_s
