"""Test-suite settings: deterministic property tests (no deadline: the 2-core CI machine is noisy)."""

from hypothesis import settings

settings.register_profile("akc", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("akc")
