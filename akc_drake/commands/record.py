"""``akc-drake record``: render (or capture) a session into a recording folder (DESIGN.md format).

``--source sim`` (default) renders the simulated operator performing ``--motion`` (I, II, tpose, lpose or a
BVH/AMC file) with the simulated RGB-D camera and writes colour, depth (after the stereo noise model),
timestamps and the ground-truth landmarks. ``--source realsense`` / ``bag:FILE`` copy a live camera or a
bag into the same format (for ``--seconds``, or the whole bag). A camera that fails mid-way (unplugged, a
timeout, a corrupt bag) ends the recording: the frames written so far stay a valid recording, a warning on
stderr says why, and the exit code is 0 (2 when not a single frame was recorded).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from akc_drake.errors import SourceError, UserError


def _check_args(args) -> None:
    if not isinstance(args.cycles, int) or args.cycles < 1:
        raise UserError(f"--cycles must be a positive integer, got {args.cycles!r}")
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise UserError(f"--seconds must be a positive number, got {args.seconds!r}")
    if not str(args.out).strip():
        raise UserError("--out: empty folder name")


def replay_note(body: str) -> str | None:
    """What to know before running ``run --source recording:DIR`` on a rendered recording of ``body``.

    A recording folder holds images only, so reading it back runs MediaPipe whatever ``--detector`` rendered it;
    MediaPipe takes the primitive (capsule) body for a person in only part of the frames.
    """
    if body != "primitive":
        return None
    return ("note: 'run --source recording:DIR' runs MediaPipe on these frames, and MediaPipe misses the primitive "
            "body in many of them; record with --body skinned to replay a recording through MediaPipe")


def _record_sim(args, out: Path) -> int:
    from tqdm import tqdm

    from akc_drake.core.camera import CameraIntrinsics
    from akc_drake.io.recording import RecordingWriter
    from akc_drake.operator.retarget import motion_from_spec, parse_joint_names
    from akc_drake.systems.depth_camera_source import render_session

    if args.seconds is not None:
        raise UserError("--seconds applies to live or bag sources; for --source sim use --cycles")
    intrinsics = CameraIntrinsics()
    motion = motion_from_spec(
        args.motion, cycles=args.cycles, seed=args.seed, skeleton=args.skeleton, rate_hz=intrinsics.rate_hz,
        names=parse_joint_names(args.joint_names) if args.joint_names else None,
    )
    n = len(motion.frame_times(intrinsics.rate_hz))
    t0 = time.perf_counter()
    with (
        RecordingWriter(out, intrinsics) as writer,
        tqdm(total=n, desc=f"record {motion.name}", unit="frame", file=sys.stderr, disable=None) as bar,
    ):

        def write(frame):
            writer.write(frame.t, frame.color, frame.depth_m, frame.truth_C)

        session = render_session(
            motion,
            intrinsics,
            seed=args.seed,
            frame_callback=write,
            progress=lambda k, T: bar.update(1),
            body=getattr(args, "body", "primitive"),
            detector=getattr(args, "detector", "sim"),
        )
    elapsed = time.perf_counter() - t0
    found = float(np.mean(np.isfinite(session.pixels).any(axis=(1, 2))))
    print(
        f"akc-drake record: wrote {len(session)} frames of motion {motion.name} to {out} "
        f"({1e3 * float(session.render_s.mean()):.1f} ms render per frame, {elapsed:.1f} s in all); "
        f"the {getattr(args, 'detector', 'sim')} detector found the person in {100 * found:.0f} % of them"
    )
    note = replay_note(getattr(args, "body", "primitive"))
    if note:
        print(note, file=sys.stderr)
    return 0


def _record_device(args, out: Path) -> int:
    from tqdm import tqdm

    from akc_drake.io.recording import RecordingWriter
    from akc_drake.io.sources import open_source

    opts = {"seconds": args.seconds} if args.seconds is not None else {}
    source = open_source(args.source, **opts)
    if source is None:  # pragma: no cover - "sim" is handled by the caller
        raise UserError(f"--source {args.source!r}: nothing to record")
    count = 0
    t_first = None
    error = None
    try:
        with (
            RecordingWriter(out, source.intrinsics) as writer,
            tqdm(desc=f"record {args.source}", unit="frame", file=sys.stderr, disable=None) as bar,
        ):
            frames = iter(source)
            while True:
                try:
                    frame = next(frames)
                except StopIteration:
                    break
                except Exception as e:  # the camera failed mid-run: keep what was recorded (see below)
                    error = e
                    break
                if t_first is None:
                    t_first = frame.t
                t = frame.t - t_first
                if args.seconds is not None and t > args.seconds:
                    break
                writer.write(t, frame.color, frame.depth_m, None)
                count += 1
                bar.update(1)
        # Leaving the block closed the writer: timestamps.csv lists exactly the frames written.
    finally:
        source.close()
    if error is not None:
        reason = " ".join(str(error).split()) or type(error).__name__
        if count == 0:
            raise SourceError(f"--source {args.source}: no frame recorded ({reason})")
        print(f"warning: the source stopped after {count} frames ({reason})", file=sys.stderr)
    print(f"akc-drake record: wrote {count} frames from {args.source} to {out}")
    return 0


def main(args) -> int:
    """Run ``akc-drake record`` with parsed ``args`` (see ``akc_drake.cli``); returns the exit code."""
    _check_args(args)
    out = Path(args.out)
    source = str(args.source).strip()
    if source.lower() == "sim":
        return _record_sim(args, out)
    return _record_device(args, out)
