import json

import numpy as np
import pytest

from akc_drake.fileio import atomic_write, atomic_write_text, jsonable, write_json


def test_write_json_converts_numpy_and_non_finite(tmp_path):
    p = write_json(tmp_path / "sub" / "a.json", {"x": np.float64(1.5), "n": np.int64(2), "v": np.arange(3),
                                                 "bad": float("nan"), "flag": np.bool_(True)})
    assert json.loads(p.read_text()) == {"x": 1.5, "n": 2, "v": [0, 1, 2], "bad": None, "flag": True}
    assert jsonable((np.inf, 1)) == [None, 1]


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    p = atomic_write_text(tmp_path / "out.txt", "first\n")

    def boom(f):
        f.write(b"half a fi")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(p, boom)
    assert p.read_text() == "first\n"
    assert [q.name for q in tmp_path.iterdir()] == ["out.txt"]


def test_files_get_the_usual_permissions_not_mkstemps_0600(tmp_path):
    import os

    mask = os.umask(0o022)
    try:
        p = atomic_write_text(tmp_path / "p.txt", "x")
    finally:
        os.umask(mask)
    assert (p.stat().st_mode & 0o777) == 0o644


def test_the_umask_is_read_without_changing_it(tmp_path, monkeypatch):
    import os

    from akc_drake import fileio

    mask = os.umask(0o027)
    try:
        expected = 0o027
        assert fileio._umask() == expected and fileio._probe_umask() == expected

        def no_umask(_):
            raise AssertionError("os.umask changes the whole process's umask")

        monkeypatch.setattr(os, "umask", no_umask)
        p = atomic_write_text(tmp_path / "q.txt", "x")
        assert (p.stat().st_mode & 0o777) == 0o640
    finally:
        monkeypatch.undo()
        os.umask(mask)
