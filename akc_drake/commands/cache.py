"""``akc-drake cache``: where the render cache lives and how big it is; ``--clear`` empties it.

The cache (:mod:`akc_drake.evaluation.cache`) keeps every rendered session an evaluation or a sweep needed, keyed
by the content of its spec and of the renderer; ``$AKC_DRAKE_CACHE`` moves it (``off`` turns it off).
"""

from __future__ import annotations


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n} B"


def main(args) -> int:
    from akc_drake.evaluation.cache import cache_usage, clear_cache

    usage = cache_usage()
    if usage["path"] is None:
        print("render cache: off (AKC_DRAKE_CACHE=off)")
        return 0
    if args.clear:
        gone = clear_cache()
        print(f"render cache {gone['path']}: removed {gone['sessions']} sessions ({_size(gone['bytes'])})")
        return 0
    print(f"render cache {usage['path']}: {usage['sessions']} sessions ({_size(usage['bytes'])})")
    return 0
