"""Registry archives at install time: pinned digests, a cached download, one member out of a tarball (no network:
``file://`` URLs and local archives)."""

from __future__ import annotations

import base64
import hashlib
import io
import tarfile

import pytest

from akc_drake.errors import UserError
from akc_drake.io import registry as R


def _sri(data: bytes) -> str:
    return "sha512-" + base64.b64encode(hashlib.sha512(data).digest()).decode()


def test_digests_in_both_pinned_forms():
    data = b"some archive"
    R.check_digest("a.tgz", data, _sri(data))
    R.check_digest("a.tar.gz", data, hashlib.sha256(data).hexdigest())
    with pytest.raises(UserError, match=r"^a\.tgz: SHA-512 sha512-\S+ differs from the pinned sha512-"):
        R.check_digest("a.tgz", data + b"!", _sri(data))
    with pytest.raises(UserError, match=r"^pkg:m\.bvh: SHA-256 [0-9a-f]{64} differs from the pinned [0-9a-f]{64}$"):
        R.check_digest("pkg:m.bvh", data + b"!", hashlib.sha256(data).hexdigest())
    with pytest.raises(ValueError, match="not a pinned digest"):
        R.check_digest("a", data, "md5-xyz")


def test_fetch_downloads_once_and_refuses_other_bytes(tmp_path):
    src = tmp_path / "registry" / "pose.tgz"
    src.parent.mkdir()
    src.write_bytes(b"tarball bytes")
    pinned = _sri(b"tarball bytes")
    dest = tmp_path / "cache" / "pose.tgz"
    assert R.fetch_url(src.as_uri(), dest, pinned) == dest
    assert dest.read_bytes() == b"tarball bytes"
    src.unlink()  # the registry is gone: the cached copy is used as it is
    assert R.fetch_url(src.as_uri(), dest, pinned) == dest
    dest.write_bytes(b"truncated")  # a bad cached copy is fetched again, here from nowhere: one line
    with pytest.raises(UserError, match=r"pose\.tgz: cannot download"):
        R.fetch_url(src.as_uri(), dest, pinned)
    src.write_bytes(b"altered bytes")
    with pytest.raises(UserError, match=r"pose\.tgz: SHA-512 .* differs from the pinned"):
        R.fetch_url(src.as_uri(), tmp_path / "cache" / "other.tgz", pinned)
    assert not (tmp_path / "cache" / "other.tgz").exists()


def test_archive_member(tmp_path):
    tgz = tmp_path / "p.tgz"
    with tarfile.open(tgz, "w:gz") as tf:
        info = tarfile.TarInfo("package/a.tflite")
        info.size = 3
        tf.addfile(info, io.BytesIO(b"abc"))
    assert R.archive_member(tgz, "package/a.tflite") == b"abc"
    with pytest.raises(UserError, match=r"p\.tgz: no file package/b\.tflite"):
        R.archive_member(tgz, "package/b.tflite")
    (tmp_path / "bad.tgz").write_bytes(b"not gzip")
    with pytest.raises(UserError, match=r"bad\.tgz: cannot read the archive"):
        R.archive_member(tmp_path / "bad.tgz", "x")
