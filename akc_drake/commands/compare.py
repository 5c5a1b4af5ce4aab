"""``akc-drake compare``: real-motion evaluations side by side, and what changed between two.

``akc-drake compare RUN.json|DIR [...]`` (a folder: its ``*.json`` runs, by name) prints one row per run and corrected
method: its worst increase over its filter, over all frames and the frames a joint is seen, in 3D, the lost
joint-frames and the pooled arm 3D RMSE. ``--against OLD.json [...]`` pairs each run with an earlier one of the same
clips (in order; one folder: by file name) and prints what moved: the worst figures before -> after, and every
(method, clip, joint, axis) that crossed the target or moved by ``--min-change`` cm. ``--methods`` keeps only the
corrected methods named; ``--json FILE`` writes the same as data. See :mod:`akc_drake.evaluation.compare`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from akc_drake.errors import UserError


def _load(args) -> list[tuple[Path, dict]]:
    """The runs named, each read once, with its path: a file, or a folder whose ``*.json`` files that are
    real-motion evaluations are the runs (sorted by name; any other JSON there is skipped, and said so)."""
    from akc_drake.evaluation.compare import load_run

    out: list[tuple[Path, dict]] = []
    for a in args:
        p = Path(a)
        if not p.is_dir():
            out.append((p, load_run(p)))
            continue
        found = []
        for f in sorted(p.glob("*.json")):
            try:
                found.append((f, load_run(f)))
            except ValueError as e:
                print(f"akc-drake compare: skipped {e}", file=sys.stderr)
        if not found:
            raise UserError(f"{p}: no real-motion evaluation (.json) in the folder")
        out += found
    return out


def main(args) -> int:
    from akc_drake.evaluation.compare import changes, format_changes, format_glance, glance
    from akc_drake.evaluation.report import write_json

    if args.target <= 0 or args.min_change <= 0:
        raise UserError("--target and --min-change must be positive numbers of centimetres")
    new, old = _load(args.runs), _load(args.against or [])
    if len(args.against or []) == 1 and Path(args.against[0]).is_dir():
        # (a folder of earlier runs: each run paired with the earlier one of its file name)
        by_name = {p.name: (p, r) for p, r in old}
        missing = [str(p) for p, _ in new if p.name not in by_name]
        if missing:
            raise UserError(f"--against {args.against[0]}: no earlier run named as {', '.join(missing)}")
        old = [by_name[p.name] for p, _ in new]
    paths = [p for p, _ in new + old]
    runs, olds = [r for _, r in new], [r for _, r in old]
    labels = [r["label"] for r in runs + olds]
    for r, path in zip(runs + olds, paths, strict=True):
        if labels.count(r["label"]) > 1:  # (the same file name in two folders: told apart by their paths)
            r["label"] = str(path)
    if olds and len(olds) != len(runs):
        raise UserError(f"--against: {len(olds)} runs for {len(runs)}; give one earlier run per run, in order, "
                        f"or a folder of them")
    rows = glance(runs)
    if args.methods:
        keep = {m.strip() for m in args.methods.split(",") if m.strip()}
        have = {r["method"] for r in rows}
        if not keep <= have:
            raise UserError(f"--methods: {', '.join(sorted(keep - have))} not in the runs "
                            f"(they have {', '.join(sorted(have))})")
        rows = [r for r in rows if r["method"] in keep]
    print(format_glance(rows, args.target))
    out = {"target_cm": args.target, "runs": rows, "changes": []}
    for old, new in zip(olds, runs, strict=False):
        ch = changes(old, new, args.target, args.min_change)
        if args.methods:
            ch = {"summary": [x for x in ch["summary"] if x["method"] in keep],
                  "entries": [x for x in ch["entries"] if x["method"] in keep]}
        print(f"\n{old['label']} -> {new['label']}:\n")
        print(format_changes(ch, args.target))
        out["changes"].append({"old": old["label"], "new": new["label"], **ch})
    if args.json:
        write_json(args.json, out)
    return 0
