"""Test-suite settings.

* Property tests are deterministic: derandomized, no deadline (the 2-core CI machine is noisy) and no example
  database (two pytest-xdist workers would share ``.hypothesis/``; derandomized runs do not need it).
* The suite runs in a random order (pytest-randomly, which also reseeds ``random`` and numpy's global generator
  before every test) and on two workers (``make test`` passes ``-n 2``): tests write only under ``tmp_path``
  and keep no state between tests beyond read-only module fixtures.
* The render cache (``AKC_DRAKE_CACHE``) is private to each test session.
"""

import os

import pytest
from hypothesis import settings

settings.register_profile("akc", deadline=None, derandomize=True, print_blob=True, database=None)
settings.load_profile("akc")


@pytest.fixture(scope="session", autouse=True)
def _private_render_cache(tmp_path_factory):
    """Each test session (each xdist worker) gets its own render cache, so no result depends on what an earlier
    run, another worker or an older version of the renderer left in ``~/.cache/akc-drake``."""
    old = os.environ.get("AKC_DRAKE_CACHE")
    os.environ["AKC_DRAKE_CACHE"] = str(tmp_path_factory.mktemp("akc-drake-cache"))
    yield
    if old is None:
        os.environ.pop("AKC_DRAKE_CACHE", None)
    else:
        os.environ["AKC_DRAKE_CACHE"] = old
