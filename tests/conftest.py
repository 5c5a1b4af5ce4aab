"""Test-suite settings.

* Property tests are deterministic: derandomized, no deadline (the 2-core CI machine is noisy) and no example
  database (two pytest-xdist workers would share ``.hypothesis/``; derandomized runs do not need it).
* The suite runs in a random order (pytest-randomly, which also reseeds ``random`` and numpy's global generator
  before every test) and on two workers (``make test`` passes ``-n 2``): tests write only under ``tmp_path``
  and keep no state between tests beyond read-only module fixtures.
"""

from hypothesis import settings

settings.register_profile("akc", deadline=None, derandomize=True, print_blob=True, database=None)
settings.load_profile("akc")
