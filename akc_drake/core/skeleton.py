"""Landmark and segment names, the BlazePose index map and the operator's body dimensions.

Conventions (see DESIGN.md):

* Landmark arrays are ``(J, 3)`` or ``(T, J, 3)`` float64 in metres, NaN where missing, with the
  landmarks in the order of :data:`LANDMARKS`.
* "left" is the operator's left.
* Segments: ``LUA``/``RUA`` upper arm (shoulder-elbow), ``LLA``/``RLA`` lower arm (elbow-wrist),
  ``SW`` shoulder width (left shoulder - right shoulder).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from types import MappingProxyType

import numpy as np

#: The 12 landmarks the pipeline uses, in array order (the same order as BlazePose's indices).
LANDMARKS: tuple[str, ...] = (
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_pinky",
    "right_pinky",
    "left_index",
    "right_index",
    "left_hip",
    "right_hip",
)
NUM_LANDMARKS = len(LANDMARKS)

#: Index of each landmark name in :data:`LANDMARKS`.
INDEX: MappingProxyType = MappingProxyType({name: i for i, name in enumerate(LANDMARKS)})

#: BlazePose / MediaPipe Pose (33 landmarks) index of each of our landmarks.
BLAZEPOSE_INDEX: MappingProxyType = MappingProxyType(
    {
        "left_shoulder": 11,
        "right_shoulder": 12,
        "left_elbow": 13,
        "right_elbow": 14,
        "left_wrist": 15,
        "right_wrist": 16,
        "left_pinky": 17,
        "right_pinky": 18,
        "left_index": 19,
        "right_index": 20,
        "left_hip": 23,
        "right_hip": 24,
    }
)
#: For each of our landmarks in order, its BlazePose index: ``blaze[BLAZEPOSE_ORDER]`` -> ours.
BLAZEPOSE_ORDER: np.ndarray = np.array([BLAZEPOSE_INDEX[n] for n in LANDMARKS], dtype=np.intp)

#: The six arm joints evaluated in the paper's tables (and the joints AKC/COIK correct).
ARM_JOINTS: tuple[str, ...] = (
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
)
ARM_JOINT_INDICES: np.ndarray = np.array([INDEX[n] for n in ARM_JOINTS], dtype=np.intp)

SIDES: tuple[str, ...] = ("left", "right")

#: Segment name -> (proximal landmark, distal landmark).
SEGMENTS: MappingProxyType = MappingProxyType(
    {
        "LUA": ("left_shoulder", "left_elbow"),
        "LLA": ("left_elbow", "left_wrist"),
        "RUA": ("right_shoulder", "right_elbow"),
        "RLA": ("right_elbow", "right_wrist"),
        "SW": ("left_shoulder", "right_shoulder"),
    }
)
SEGMENT_NAMES: tuple[str, ...] = tuple(SEGMENTS)

_PROXIMAL_DISTAL = (
    ("shoulder", "elbow"),
    ("shoulder", "wrist"),
    ("elbow", "wrist"),
    ("shoulder", "index"),
    ("shoulder", "pinky"),
    ("elbow", "index"),
    ("elbow", "pinky"),
)

#: Pairs (proximal, distal) for the occlusion filter's proximity check: a proximal joint's depth
#: is dropped when its pixel lies near the pixel of one of its distal joints, on the same arm or on the
#: other (a hand across the chest hides the opposite shoulder: with MediaPipe on the skinned body,
#: bvhtools_a1's left shoulder read 13-20 cm in front in 41 % of its frames, the right hand 5-25 px away).
PROXIMAL_DISTAL_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (f"{side}_{prox}", f"{other}_{dist}")
    for side in SIDES
    for other in (side, *(o for o in SIDES if o != side))
    for prox, dist in _PROXIMAL_DISTAL
)


#: The paper's pairs (§II-C): "the depth of a proximal joint (e.g., elbow or shoulder) is discarded when its
#: projected 2D position lies within a small neighborhood ... of a distal joint (e.g., wrist)". Ours above add
#: shoulder-elbow (the upper arm pointing at the camera hides the shoulder behind the elbow) and the knuckles.
PAPER_PROXIMAL_DISTAL_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (f"{side}_{prox}", f"{side}_wrist") for side in SIDES for prox in ("shoulder", "elbow")
)


def idx(name: str) -> int:
    """Index of landmark ``name`` in :data:`LANDMARKS` (``KeyError`` naming the landmark otherwise)."""
    try:
        return INDEX[name]
    except KeyError:
        raise KeyError(f"unknown landmark {name!r}; known: {', '.join(LANDMARKS)}") from None


def side_indices(side: str) -> tuple[int, int, int]:
    """(shoulder, elbow, wrist) indices for ``side`` in {"left", "right"}."""
    if side not in SIDES:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    return INDEX[f"{side}_shoulder"], INDEX[f"{side}_elbow"], INDEX[f"{side}_wrist"]


#: Largest length accepted for any segment, metres (anything longer is a unit or input mistake).
MAX_SEGMENT_M = 1.5


@dataclass(frozen=True)
class BodyDimensions:
    """The operator's arm segment lengths and shoulder width, in metres.

    Attributes:
        LUA: left upper arm (shoulder-elbow).
        LLA: left lower arm (elbow-wrist).
        RUA: right upper arm.
        RLA: right lower arm.
        SW: shoulder width (left shoulder-right shoulder).

    Every value must be finite and in (0, 1.5] m; a ``ValueError`` names the field otherwise.
    """

    LUA: float
    LLA: float
    RUA: float
    RLA: float
    SW: float

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"BodyDimensions.{f.name} must be a number, got {value!r}") from None
            if not math.isfinite(v) or v <= 0.0:
                raise ValueError(f"BodyDimensions.{f.name} must be a positive finite length in metres, got {value!r}")
            if v > MAX_SEGMENT_M:
                raise ValueError(
                    f"BodyDimensions.{f.name} = {v:g} m is longer than {MAX_SEGMENT_M} m; lengths are in metres"
                )
            object.__setattr__(self, f.name, v)

    @classmethod
    def paper_participant(cls) -> BodyDimensions:
        """The paper's participant as measured by Vicon (Table VIII, Vicon column)."""
        return cls(LUA=0.288, LLA=0.280, RUA=0.289, RLA=0.270, SW=0.332)

    @classmethod
    def paper_manual(cls) -> BodyDimensions:
        """The paper's participant as measured with a ruler (Table VIII, Manual column)."""
        return cls(LUA=0.32, LLA=0.26, RUA=0.32, RLA=0.26, SW=0.33)

    def upper(self, side: str) -> float:
        """Upper-arm length of ``side``."""
        return self.LUA if side == "left" else self.RUA

    def lower(self, side: str) -> float:
        """Lower-arm (forearm) length of ``side``."""
        return self.LLA if side == "left" else self.RLA

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def as_array(self) -> np.ndarray:
        """``[LUA, LLA, RUA, RLA, SW]``."""
        return np.array([self.LUA, self.LLA, self.RUA, self.RLA, self.SW])

    @classmethod
    def from_dict(cls, d: dict, *, where: str = "dimensions") -> BodyDimensions:
        """Build from a mapping with keys LUA, LLA, RUA, RLA, SW (metres).

        Raises:
            ValueError: naming ``where`` and the missing or unknown key.
        """
        if not isinstance(d, dict):
            keys = ", ".join(SEGMENT_NAMES)
            raise ValueError(f"{where}: expected a mapping with keys {keys}, got {type(d).__name__}")
        missing = [k for k in SEGMENT_NAMES if k not in d]
        unknown = [k for k in d if k not in SEGMENT_NAMES]
        if missing:
            raise ValueError(f"{where}: missing {', '.join(missing)}")
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {', '.join(map(str, unknown))}")
        try:
            return cls(**{k: d[k] for k in SEGMENT_NAMES})
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None


def segment_lengths(pose: np.ndarray) -> dict[str, np.ndarray]:
    """Lengths of every segment of a pose ``(J, 3)`` or trajectory ``(T, J, 3)``; NaN where missing."""
    pose = np.asarray(pose, dtype=float)
    out = {}
    for name, (a, b) in SEGMENTS.items():
        out[name] = np.linalg.norm(pose[..., INDEX[a], :] - pose[..., INDEX[b], :], axis=-1)
    return out


def check_pose(pose, *, name: str = "pose", allow_trajectory: bool = False) -> np.ndarray:
    """Return ``pose`` as float64 ``(J, 3)`` (or ``(T, J, 3)``), or raise a ``ValueError`` naming it."""
    a = np.asarray(pose, dtype=float)
    ok = a.shape == (NUM_LANDMARKS, 3) or (allow_trajectory and a.ndim == 3 and a.shape[1:] == (NUM_LANDMARKS, 3))
    if not ok:
        want = f"({NUM_LANDMARKS}, 3)" + (f" or (T, {NUM_LANDMARKS}, 3)" if allow_trajectory else "")
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    return a
