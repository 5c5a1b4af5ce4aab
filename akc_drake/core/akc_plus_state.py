"""AKC+'s state as one flat vector (a Drake system's discrete state): :class:`StateVector`, a mixin of
:class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus`.

Layout (:data:`STATE_SIZE` floats): per side the last output's shoulder, elbow, wrist xyz ``[0:18]``, two validity
flags ``[18:20]``, four untrusted-frame counters ``[20:24]``, the filter's estimate of each elbow and shoulder when
last seen ``[24:36]``, the running NIS means ``[36:54]``, then per side (x, y, z, frames) the held forearm
``[54:62]``, the held upper arm ``[62:70]`` and the shoulder's offset from the hips' centre ``[70:78]``, and per
side the upper arm when the held forearm was kept (x, y, z; NaN once the forearm no longer turns with it)
``[78:84]``, per side (x, y, z, frames) the shoulder's offset from the other shoulder ``[84:92]``, and the frames
since the hips were last the torso's reference ``[92]``, and per side the measured depth's running-mean difference
from the other shoulder's (NaN: none yet), the frames it has held the shoulder, the depth last measured and the
frames since ``[93:101]``, and per side the elbow's depth read where our output was judged behind the surface it
read (NaN: none; :class:`~akc_drake.core.akc_plus_lengths.SurfaceMemory`) ``[101:103]``, and per side the frames
the wrist was read misread since the held forearm was taken (NaN: no forearm held;
:func:`~akc_drake.core.akc_plus_evidence.held_segments`) ``[103:105]``, and per side and joint (shoulder, elbow,
wrist) the last depth residual (NaN: not read last frame) and the running reading noise
(:func:`~akc_drake.core.akc_plus_evidence.depth_reading_noise`) ``[105:117]``, and per side the running means from
which the elbow's landmark offset is learnt (:func:`~akc_drake.core.akc_plus_lengths.learn_elbow_offset`) ``[117:121]``.
"""

from __future__ import annotations

import math

import numpy as np

from akc_drake.core.skeleton import SIDES

STATE_SIZE = 121
_NIS, _BLIND, _BLIND_E, _HELD, _BLIND_U, _HELD_SS, _HIPS_LOST, _PAIR_Z, _READ_E = 36, 54, 62, 70, 78, 84, 92, 93, 101
_MISREAD, _NOISE, _ELBOW = 103, 105, 117


class StateVector:
    """:meth:`reset`, :meth:`get_state_vector` and :meth:`set_state_vector` of AKC+ (its attributes ``_prev``,
    ``_lost``, ``_f0``, ``_travel``, ``_nis``, ``_blind``, ``_blind_e``, ``_held_sh``, ``_held_ss``, ``_hips_lost``,
    ``_pair_z``, ``_read_e``, ``_depth_noise``, ``_e_acc``)."""

    __slots__ = ()

    def reset(self) -> None:
        """Forget the previous output and the untrusted-frame counters."""
        self._prev: list[tuple | None] = [None, None]
        self._lost = [0.0, 0.0, 0.0, 0.0]  # frames without a trusted depth: (left elbow, left shoulder, right ...)
        self._f0: list[tuple | None] = [None, None, None, None]  # the filter's estimate when last seen
        self._travel = [0.0, 0.0, 0.0, 0.0]  # how far it has moved since
        self._nis = [1.0] * 18  # running mean NIS per arm joint and axis (left s, e, w, right s, e, w)
        # per side: the forearm (wrist - elbow) of our last output with the wrist detected, the frames since, the
        # upper arm (elbow - shoulder) of that output, which the held forearm turns with (NaN: no longer turns), and
        # the frames the wrist was read misread since
        self._blind: list[list | None] = [None, None]
        self._blind_e: list[list | None] = [None, None]  # the upper arm (elbow - shoulder) likewise
        # per side: the shoulder minus the hips' centre (x, y, z) in our outputs with its depth measured (a running
        # mean, weight ``shoulder_alpha``), and the frames since the last
        self._held_sh: list[list | None] = [None, None]
        # per side: the shoulder minus the other shoulder (``TorsoReference._other_anchor``) likewise, learnt while
        # the hips are no torso reference: the reference after they have been none for ``hips_lost_frames``
        self._held_ss: list[list | None] = [None, None]
        self._hips_lost = 0.0  # frames since the hips were last the torso's reference (or since the start)
        # per side: the measured depth minus the other shoulder's (a running mean; NaN: none yet), the frames it has
        # held the shoulder, the depth last measured and the frames since (``TorsoReference._shoulder_jumped``)
        self._pair_z = [[math.nan, 0.0, math.nan, 0.0], [math.nan, 0.0, math.nan, 0.0]]
        # per side: the elbow's depth read last frame where a rule put the elbow behind it (``SurfaceMemory``)
        self._read_e = [math.nan, math.nan]
        # per side and joint: the depth read less the filter's last frame, and the reading's noise variance (its
        # running mean; ``seen_depth_sigma_m`` squared until frames have measured it)
        self._depth_noise = [math.nan, self.config.seen_depth_sigma_m**2] * 6
        # per side: the running means ``learn_elbow_offset`` regresses (from a prior worth half a straight arm at the
        # projections' offset variance), and what they add to the elbow's variances
        v0 = 0.5 * self.config.length_sigma_m**2
        self._e_acc, self._e_var = [[0.5 * v0, 0.5], [0.5 * v0, 0.5]], [0.0, 0.0]

    def get_state_vector(self) -> np.ndarray:
        """``(STATE_SIZE,)``: per side shoulder, elbow, wrist xyz (NaN if none), 2 validity flags, 4 counters, the
        filter's estimate of each elbow/shoulder in the last frame its depth was seen (NaN if none), the running
        NIS means, per side the held forearm, then upper arm, and its blind frames, the held shoulder offset and
        its frames, then per side the upper arm the held forearm turns with, the shoulder's offset from the
        other shoulder and its frames, the frames since the hips were the torso's reference, and per side the
        shoulders' measured depth difference, its held frames, the depth last measured and the frames since, per
        side the elbow's reading judged in front of it, per side the held forearm's misread frames, per side
        and joint the last depth residual and the reading noise, and per side the elbow offset's running means."""
        v = np.full(STATE_SIZE, np.nan)
        for side in (0, 1):
            p = self._prev[side]
            if p is not None:
                v[9 * side : 9 * side + 9] = p
            v[18 + side] = 0.0 if p is None else 1.0
        v[20:24] = self._lost
        for k in range(4):
            if self._f0[k] is not None:
                v[24 + 3 * k : 27 + 3 * k] = self._f0[k]
        v[_NIS:_BLIND] = self._nis
        for base, per_side in ((_BLIND, self._blind), (_BLIND_E, self._blind_e), (_HELD, self._held_sh),
                               (_HELD_SS, self._held_ss)):
            for side in (0, 1):
                if per_side[side] is not None:
                    v[base + 4 * side : base + 4 * side + 4] = per_side[side][:4]
        for side in (0, 1):
            if self._blind[side] is not None:
                v[_BLIND_U + 3 * side : _BLIND_U + 3 * side + 3] = self._blind[side][4:7]
                v[_MISREAD + side] = self._blind[side][7]
        v[_HIPS_LOST] = self._hips_lost
        v[_PAIR_Z:_READ_E] = self._pair_z[0] + self._pair_z[1]
        v[_READ_E:_MISREAD] = self._read_e
        v[_NOISE:_ELBOW] = self._depth_noise
        v[_ELBOW:STATE_SIZE] = self._e_acc[0] + self._e_acc[1]
        return v

    def set_state_vector(self, v) -> None:
        """Restore :meth:`get_state_vector`'s vector.

        Raises:
            ValueError: naming the wrong shape, a bad flag or counter, or non-finite joints of a valid arm.
        """
        a = np.asarray(v, dtype=float)
        if a.shape != (STATE_SIZE,):
            raise ValueError(f"AKC+ state vector must have shape ({STATE_SIZE},), got {a.shape}")
        prev: list[tuple | None] = [None, None]
        for side in (0, 1):
            flag = a[18 + side]
            if flag not in (0.0, 1.0):
                raise ValueError(f"AKC+ state vector: validity flag [{18 + side}] must be 0 or 1, got {flag!r}")
            if flag == 1.0:
                joints = a[9 * side : 9 * side + 9]
                if not np.all(np.isfinite(joints)):
                    raise ValueError(f"AKC+ state vector: {SIDES[side]} arm is flagged valid but not finite")
                prev[side] = tuple(joints.tolist())
        lost = a[20:24]
        if not np.all(np.isfinite(lost) & (lost >= 0)):
            raise ValueError(f"AKC+ state vector: counters [20:24] must be >= 0, got {lost.tolist()}")
        f0 = [a[24 + 3 * k : 27 + 3 * k] for k in range(4)]
        f0 = [tuple(q.tolist()) if np.all(np.isfinite(q)) else None for q in f0]
        self._prev = prev
        self._lost = lost.tolist()
        nis = a[_NIS:_BLIND]
        if not np.all(np.isfinite(nis) & (nis > 0)):
            raise ValueError(f"AKC+ state vector: NIS means [{_NIS}:{_BLIND}] must be > 0, got {nis.tolist()}")
        blocks = []  # the forearms, the upper arms, the held shoulders: per side 3 floats and a frame count
        for base, what in ((_BLIND, "blind-frame"), (_BLIND_E, "blind-elbow frame"), (_HELD, "held-shoulder frame"),
                           (_HELD_SS, "shoulder-pair frame")):
            per_side: list[list | None] = [None, None]
            for side in (0, 1):
                b = a[base + 4 * side : base + 4 * side + 4]
                if np.all(np.isfinite(b)):
                    if b[3] < 0:
                        raise ValueError(f"AKC+ state vector: {what} count [{base + 4 * side + 3}] must be >= 0")
                    per_side[side] = b.tolist()
            blocks.append(per_side)
        for side in (0, 1):  # the held forearm's upper arm (NaN: it no longer turns with it), its misread frames
            if blocks[0][side] is not None:
                u = a[_BLIND_U + 3 * side : _BLIND_U + 3 * side + 3]
                blocks[0][side] += u.tolist() if np.all(np.isfinite(u)) else [np.nan] * 3
                k = a[_MISREAD + side]
                if not (math.isfinite(k) and k >= 0):
                    raise ValueError(f"AKC+ state vector: misread-frame count [{_MISREAD + side}] must be >= 0, "
                                     f"got {k!r}")
                blocks[0][side].append(float(k))
        self._blind, self._blind_e, self._held_sh, self._held_ss = blocks
        hl = a[_HIPS_LOST]
        if not (math.isfinite(hl) and hl >= 0):
            raise ValueError(f"AKC+ state vector: hips-lost frames [{_HIPS_LOST}] must be >= 0, got {hl!r}")
        self._hips_lost = float(hl)
        pz = a[_PAIR_Z:_READ_E].tolist()
        for i in (1, 3, 5, 7):
            if not (math.isfinite(pz[i]) and pz[i] >= 0):
                raise ValueError(f"AKC+ state vector: shoulder-pair frame count [{_PAIR_Z + i}] must be >= 0, "
                                 f"got {pz[i]!r}")
        self._pair_z = [pz[0:4], pz[4:8]]
        read = a[_READ_E:_MISREAD]
        if np.any(np.isinf(read)):
            raise ValueError(f"AKC+ state vector: elbow readings [{_READ_E}:{_MISREAD}] must be finite or NaN, "
                             f"got {read.tolist()}")
        self._read_e = read.tolist()
        noise = a[_NOISE:_ELBOW]
        if np.any(np.isinf(noise[0::2])) or not np.all(np.isfinite(noise[1::2]) & (noise[1::2] >= 0)):
            raise ValueError(f"AKC+ state vector: depth residuals [{_NOISE}:{_ELBOW}:2] must be finite or NaN "
                             f"and reading noises [{_NOISE + 1}:{_ELBOW}:2] >= 0, got {noise.tolist()}")
        elbow = a[_ELBOW:STATE_SIZE]
        if not (np.all(np.isfinite(elbow)) and np.all(elbow[1::2] >= 0)):
            raise ValueError(f"AKC+ state vector: the elbow offset's means [{_ELBOW}:{STATE_SIZE}] must be finite, "
                             f"[{_ELBOW + 1}:{STATE_SIZE}:2] >= 0, got {elbow.tolist()}")
        self._depth_noise = noise.tolist()
        self._e_acc = [elbow[0:2].tolist(), elbow[2:4].tolist()]
        self._f0 = f0
        self._travel = [0.0, 0.0, 0.0, 0.0]
        self._nis = nis.tolist()
